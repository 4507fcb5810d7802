"""What the summaries of a run file, an ensemble directory and records share: the error they
raise (:class:`InfoError`), durations and sizes as text, and the configuration block that ends
the summary of a run or a record (:func:`config_lines`: every key as TOML, written by
:func:`tiltpile.config.config_toml`)."""

from __future__ import annotations

from tiltpile import config as cfgmod


class InfoError(ValueError):
    """A path that is not a readable run file or ensemble directory (the message names it)."""


def duration(seconds: float) -> str:
    """``1 h 02 min``, ``3 min 05 s`` or ``12.3 s``."""
    if seconds >= 3600:
        return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"
    if seconds >= 60:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{seconds:.1f} s"


def human_size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} GB"


def complete_config(config: dict) -> dict:
    """Every key of the configuration, the ones a run file leaves out at their defaults included
    (``config.LATER_KEYS`` are stored only when set), so that the TOML of
    :func:`tiltpile.config.config_toml` reproduces the run over any preset. A configuration this
    version cannot validate (a run of another version) is returned as stored."""
    try:
        return cfgmod.from_dict(config).to_dict()
    except (cfgmod.ConfigError, TypeError, ValueError):
        return config


def config_lines(config: dict, seed: int) -> list[str]:
    """The block that ends a run's or a record's summary: a blank line, how to reuse it, and its
    configuration as TOML (:func:`complete_config`): ``tiltpile simulate --config FILE`` with it
    reproduces the run's configuration hash whatever the preset."""
    return ["", "# configuration (reuse: tiltpile simulate --config FILE.toml --seed "
                f"{seed} --out RUN.h5)",
            cfgmod.config_toml(complete_config(config)).rstrip()]
