"""The presets' scale axis: one TOML file per scale of ``tiltpile.config.PRESET_SCALES``
(``<scale>.toml``: the pile, box, solver and ramp, what it changes from the defaults), read by
``config.compose_preset``, which adds the history and the engine of a preset's triple (declared
in ``config.py``: ``PRESET_HISTORIES``, ``PRESET_ENGINES``; the named presets, ``PRESET_TABLE``).
What each preset is for: docs/presets.md; ``tiltpile presets`` lists them."""
