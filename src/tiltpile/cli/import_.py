"""``tiltpile import``: another code's tilted pile (LAMMPS dumps, or the plain format: NPZ per
frame or a CSV set) into a run file that ``observables``, ``record``, the figures and the report
read unchanged (docs/import.md; ``tiltpile.importers``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tiltpile.cli._common import check_output, seed

INTERRUPTED = "interrupted; nothing was written"

DESCRIPTION = """\
Turn a tilted pile simulated or measured elsewhere into a run file (docs/import.md).

INPUT is one of (the format is told from the inputs):
  LAMMPS dumps   dump custom files of the atoms (one or many frames each, .gz too), with
                 --contacts: the dump local files of the contacts (compute property/local
                 patom1 patom2 beside compute pair/local force ...), joined by timestep
  NPZ frames     one .npz per frame (or a directory of them), the plain format's fields
  a CSV set      a directory holding frames.csv, grains.csv and contacts.csv, each row with
                 its frame number (column frame) and the same fields

The plain format's fields ([optional]): per frame step, theta_deg [deg] (or the gravity vector
gx, gy), [time]; per grain x, y, radius, [id, fixed (0/1), vx, vy, omega, rotation]; per
contact id1, id2 (grain ids, or a wall: -1 floor, -2 left, -3 right), fn, ft (the force on
id1 is fn n + ft t, n from id2 to id1, t = (-n_y, n_x)), [sliding (0/1)].

Every frame is checked before anything is written (missing or unknown fields, NaN, duplicate
ids, grains that change, frames out of order, an angle that goes backwards, grains outside the
box): a refusal is one line naming the field and the frame, exit status 2. Positions are in the
box frame: floor y = 0, side walls x = 0 and x = L; lengths in the mean grain diameter d unless
--length-unit. A contact is sliding where the source flags it (a sliding field or column), else
by the Coulomb test |f_t| >= mu f_n (1 - eps) (--eps).
"""

EPILOG = """\
examples:
  tiltpile import frames/ --box-length 40 --mu 0.5 --out imported/run_0000.h5
  tiltpile import dumps/atoms.*.dump --contacts dumps/contacts.*.dump --fixed-types 2 \\
      --contact-columns 'id1=c_pa[1],id2=c_pa[2],fn=c_pl[1],ftx=c_pl[2],fty=c_pl[3]' \\
      --atom-columns gx=v_gravx,gy=v_gravy --wall f_floor=floor --wall f_sides=sides \\
      --box-length 12 --mu 0.5 --out imported/run_0000.h5
then: tiltpile observables imported/   (and record, the figures, the report)
`tiltpile dem --keep-dumps DIR` writes DIR/README.txt with the command for its own dumps.
"""


def add_parser(sub) -> None:
    from tiltpile.importers import DEFAULT_EPS
    from tiltpile.importers.lammps import ATOM_ROLES, CONTACT_ROLES, PLANES

    s = sub.add_parser("import", help="another code's frames (LAMMPS dumps, NPZ or CSV) into a run file",
                       description=DESCRIPTION, epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="LAMMPS atom dumps, .npz frames, or a directory of .npz frames or of the CSV set")
    s.add_argument("--out", required=True, type=Path, metavar="RUN.h5",
                   help="run file to write (RUN.h5; name it DIR/run_SSSS.h5 for `tiltpile observables DIR`)")
    s.add_argument("--box-length", type=float, required=True, metavar="L",
                   help="distance between the side walls (x = 0 and x = L), in the input's length unit")
    s.add_argument("--mu", type=float, required=True,
                   help="friction coefficient between grains (the Coulomb test; recorded as scene.mu)")
    s.add_argument("--mu-wall", type=float, default=None, metavar="MU",
                   help="friction coefficient at the floor and side walls (default: --mu)")
    s.add_argument("--eps", type=float, default=DEFAULT_EPS,
                   help=f"a contact the source does not flag is sliding when |f_t| >= mu f_n (1 - eps) "
                        f"(default {DEFAULT_EPS:g}: above the 1e-5 that LAMMPS' default 6-digit dump "
                        "format moves |f_t| / (mu f_n); 1e-9 for full-precision dumps)")
    s.add_argument("--length-unit", type=float, default=1.0, metavar="D",
                   help="the mean grain diameter d in the input's length unit (default 1: lengths in d)")
    s.add_argument("--time-unit", type=float, default=1.0, metavar="T",
                   help="sqrt(d/g) in the input's time unit (default 1)")
    s.add_argument("--force-unit", type=float, default=1.0, metavar="F",
                   help="the weight m g of a grain of diameter d (m = rho pi d^2 / 4) in the "
                        "input's force unit (default 1)")
    s.add_argument("--seed", type=seed, default=None, metavar="S",
                   help="the run's id (the tables' run column; default: the number in --out's name)")
    s.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="set a configuration key the import derives or leaves at its default, e.g. "
                        "--set protocol.tilt_per_step_deg=0.01, so that piles imported apart share "
                        "one configuration (repeatable)")
    s.add_argument("--force", action="store_true",
                   help="replace an existing run file (only once the new one is written whole)")
    lmp = s.add_argument_group("LAMMPS dumps")
    lmp.add_argument("--contacts", nargs="+", default=[], metavar="DUMP",
                     help="the dump local files of the contacts (required with LAMMPS dumps)")
    lmp.add_argument("--contact-columns", metavar="ROLE=COLUMN,...",
                     help=f"the contact dump's columns, roles {', '.join(CONTACT_ROLES)}: the pair's "
                          "atom ids, the normal force, the tangential force on atom 1 (ft signed "
                          "along t = (-n_y, n_x), n from atom 2 to atom 1; or its vector ftx, fty), "
                          "a 0/1 sliding flag (optional)")
    lmp.add_argument("--atom-columns", metavar="ROLE=COLUMN,...",
                     help="the atom dump's columns where they differ from the defaults "
                          f"({', '.join(f'{r}={c}' for r, c in ATOM_ROLES.items() if c)}); the tilt "
                          "angle per frame as theta=COLUMN [deg] or the gravity vector gx=COLUMN,"
                          "gy=COLUMN (per-atom columns, one value per frame)")
    lmp.add_argument("--fixed-types", metavar="T[,T...]", default=None,
                     help="atom types that are fixed grains (the rough floor, wall particles)")
    lmp.add_argument("--wall", action="append", default=[], metavar="FIX=PLANE",
                     help=f"a fix wall/gran ... contacts whose per-atom columns FIX[1..3] (in contact, "
                          f"fx, fy) the atom dump holds; PLANE one of {', '.join(PLANES)} (sides: "
                          "x = 0 and x = L) (repeatable)")
    lmp.add_argument("--angles", type=Path, metavar="FILE.csv",
                     help="the tilt angle per timestep: a CSV with columns step, theta_deg (or step, "
                          "gx, gy), instead of --atom-columns theta / gx,gy")
    lmp.add_argument("--timestep", type=float, metavar="DT",
                     help="the time step, so that time = step x DT (default: ITEM: TIME of the "
                          "dumps where they hold it, else no time)")
    s.set_defaults(func=run, interrupted=INTERRUPTED)


def run(args) -> int:
    """Print the import's summary as one JSON line."""
    from tiltpile.importers import InputError, Units, import_run, reader

    out = Path(args.out)
    check_output(out, "--out")
    fixed_types = ()
    if args.fixed_types:
        try:
            fixed_types = tuple(int(t) for t in args.fixed_types.split(",") if t.strip())
        except ValueError:
            raise InputError(f"--fixed-types {args.fixed_types}: atom types are integers, e.g. 2 "
                             "or 2,3") from None
    src = reader(args.inputs, box_length=args.box_length, contacts=args.contacts,
                 atom_columns=args.atom_columns, contact_columns=args.contact_columns,
                 fixed_types=fixed_types, walls=args.wall, angles=args.angles,
                 timestep=args.timestep)
    summary = import_run(src, out, box_length=args.box_length, mu=args.mu, mu_wall=args.mu_wall,
                         eps=args.eps, units=Units(args.length_unit, args.time_unit, args.force_unit),
                         seed=args.seed, overrides=args.overrides, force=args.force)
    print(json.dumps(summary))
    return 0
