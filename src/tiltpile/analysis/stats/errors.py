"""What the statistics raise and warn when the data cannot answer."""


class InsufficientDataError(ValueError):
    """Too few samples for a meaningful estimate (the message says how many and how many needed)."""


class PoorFitWarning(RuntimeWarning):
    """A fit ran but its result is not determined by the data (the message says why)."""
