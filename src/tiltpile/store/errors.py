"""The run file's errors: one base class, ``RunFileError``, and what went wrong."""

class RunFileError(RuntimeError):
    """A run file is missing, incomplete, damaged or not a tiltpile run."""


class RunBusyError(RunFileError):
    """Another process is writing this run file (its ``NAME.lock`` is held)."""


class RunExistsError(RunFileError):
    """The run file exists and was not to be replaced."""


class MixedConfigError(RunFileError):
    """Run files of more than one configuration where one is expected (``common_config``)."""


class RunWriteError(RunFileError):
    """Writing a run file failed (disk full, no permission, ...); the message is one line."""
