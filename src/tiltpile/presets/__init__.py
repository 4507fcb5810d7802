"""The presets: one TOML file per name of ``tiltpile.config.PRESETS`` (``<name>.toml``), read by
``config.preset_dict``. Each gives what it changes from the defaults (its scale always), or from
another preset (``base = "other"``); what each is for: docs/presets.md."""
