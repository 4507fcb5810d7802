"""``tiltpile config [--preset P] [--config F] [--set k=v ...] [--json]``: every configuration key
with its meaning, unit, value, default and allowed range, and the pile's depth derived from them.

The listing is ``config.describe_keys`` (the field docs and ranges ``config.py`` validates with;
docs/cli.md's table of keys is rendered from the same function) and ``config.describe_depth``.
The text is a TOML file: the keys of the configuration with their values, everything else
comments (the ``dem`` section of a Contact Dynamics configuration and the history shorthand
commented out), so that ``tiltpile config --preset P > my.toml`` gives a file to edit and pass
back with ``--config my.toml``.
"""

from __future__ import annotations

import json
import textwrap

from tiltpile import config as cfgmod
from tiltpile.cli._common import add_config_args

WIDTH = 100


def add_parser(sub) -> None:
    p = sub.add_parser(
        "config", help="list every configuration key: meaning, unit, value, default, allowed range",
        description="Every configuration key with its meaning, unit, value (of the preset, config "
                    "file and --set values given; else the defaults, which are the default-fresh "
                    "preset), default and allowed range, as a TOML file whose comments say what "
                    "each key is; and the pile's depth in grain diameters, which no key sets "
                    "(scene.n grains in scene.box_length). A bad value is refused as by "
                    "tiltpile simulate.")
    add_config_args(p, default_preset="default-fresh")
    p.add_argument("--json", action="store_true",
                   help="print the keys and the depth as JSON instead (config.describe_keys, "
                        "config.describe_depth)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.preset is None:
        cfg = cfgmod.load_over({}, args.config, args.overrides)
        origin = "the defaults (the default-fresh preset)"
    else:
        cfg = cfgmod.load(args.preset, args.config, args.overrides)
        origin = f"preset {args.preset}"
    if args.config is not None:
        origin += f", config file {args.config}"
    if args.overrides:
        origin += ", " + " ".join(f"--set {o}" for o in args.overrides)
    keys, depth = cfgmod.describe_keys(cfg), cfgmod.describe_depth(cfg)
    if args.json:
        print(json.dumps({"origin": origin, "hash": cfg.hash(), "keys": keys, "depth": depth},
                         indent=1))
    else:
        print(listing(keys, depth, origin, cfg.hash()))
    return 0


def _comment(text: str, indent: str = "# ") -> list[str]:
    return textwrap.wrap(text, WIDTH, initial_indent=indent, subsequent_indent=indent)


def depth_lines(depth: dict) -> list[str]:
    """The derived depth as comment lines (after the [scene] keys)."""
    return ([f"# pile depth (derived; no key sets it): about {depth['depth']:.1f} d above the rough "
             "bottom row"]
            + _comment("= scene.n pi (1 + p^2/3) / (4 phi scene.box_length), p = "
                       f"scene.polydispersity, phi = {depth['packing_fraction']:.2f} the packing "
                       "fraction of a deposited pile (measured; the free surface is rough by about "
                       "a grain)", "#   ")
            + [f"#   a depth of H d takes scene.n = {depth['grains_per_depth']:.1f} H (at this "
               "box_length and polydispersity)"])


def listing(keys: list[dict], depth: dict, origin: str, digest: str) -> str:
    """The keys as a TOML file: per key, its meaning as a comment, then ``key = value`` followed
    by its unit, allowed range and default; keys not part of the configuration commented out."""
    out = [f"# tiltpile configuration: {origin}", f"# hash {digest}",
           "# per key: its meaning, then key = value  # [unit]  allowed range  default"]
    section = None
    for k in keys:
        if k["section"] != section:
            if section == "scene":
                out += [""] + depth_lines(depth)
            section = k["section"]
            absent = k["value"] is None and not k["shorthand"]
            out += ["", f"{'# ' if absent else ''}[{section}]"]
            if absent:
                out += _comment(f"(no [{section}] section in this configuration: its keys as "
                                "they would be, at their defaults)") + [""]
        out += _comment(k["meaning"] + (" (a shorthand, not stored: give protocol.cycles and "
                                        "protocol.theta_rev_deg together)"
                                        if k["shorthand"] else ""))
        tail = f"[{k['unit']}]  allowed {k['range']}"
        if k["shorthand"]:
            out.append(f"# {k['name']} = ...  # {tail}  (not set)")
            continue
        value = k["value"] if k["value"] is not None else k["default"]
        prefix = "# " if k["value"] is None else ""
        default = "(default)" if value == k["default"] else f"default {k['default']}"
        out.append(f"{prefix}{k['name']} = {value}  # {tail}  {default}")
    return "\n".join(out)
