"""``tiltpile same-piles REF DIR --out OUTDIR``: the same piles under two settings, pile against pile
and every figure number ensemble against ensemble (:mod:`tiltpile.figures.same_piles`)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("same-piles", help="two ensembles of the same seeds: pile against pile, and "
                                          "every figure number in units of its jackknife error")
    p.add_argument("ref", type=Path, metavar="REF",
                   help="the reference ensemble: a directory of run_*.h5 or of their records")
    p.add_argument("dir", type=Path, metavar="DIR", help="the ensemble compared with it (the same)")
    p.add_argument("--out", type=Path, required=True, metavar="OUTDIR",
                   help="write OUTDIR/same_piles.json and each side's figure documents "
                        "OUTDIR/LABEL/figN_*.json")
    p.add_argument("--ref-label", default=None, help="name of REF in the output (default: its "
                                                     "preset, else its directory name)")
    p.add_argument("--label", default=None, help="name of DIR in the output (same default)")
    p.add_argument("--seeds", type=int, default=None, metavar="N",
                   help="the first N common seeds only (default: every common seed; at "
                        "least 2, and 3 for the figure numbers' errors and --null)")
    p.add_argument("--null", default="none", metavar="exact|auto|K|none",
                   help="also count the figure numbers that move by chance, exchanging the two "
                        "runs of some seeds and scoring each exchange like the real pair (two "
                        "evaluations of the figures per exchange), and decide by p < 0.05: "
                        "'exact' all 2^(N-1) distinct exchanges of N seeds (p exact; at most "
                        "4096), K random ones (p's Monte-Carlo error sqrt(p(1-p)/K): 0.0097 at "
                        "p = 0.05 and K = 500), 'auto' exact up to 256 exchanges (9 seeds), else "
                        "500 random; default none")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes evaluating the figures (default 1); the study is the same, "
                        "bit for bit, with any number")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def _label(d: Path, given: str | None, ens) -> str:
    name = given or ens.meta.get("preset") or d.resolve().name
    if not name or "/" in name or name in (".", ".."):
        raise ConfigError(f"label {name!r} of {d}: give a plain name (--label, --ref-label)")
    return name


def _load(d: Path):
    from tiltpile.figures import data
    from tiltpile.record import record_files

    if not d.is_dir():
        raise ConfigError(f"{d}: no such ensemble directory")
    if not sorted(d.glob("run_*.h5")) and not record_files(d):
        raise ConfigError(f"{d}: no run_*.h5 files nor records run_*.npz to compare")
    preset = _preset_of(d)
    return data.load(d, preset, cutoff=0.02, lost_gap=None)


def _preset_of(d: Path) -> str | None:
    """The preset named by the directory's manifest, or by its records' parent directory
    (figures/PRESET/records), or None."""
    from tiltpile.ensemble import read_manifest
    m = read_manifest(d) if (d / "ensemble.json").exists() else None
    if m and m.get("preset"):
        return m["preset"]
    from tiltpile import config as cfgmod
    parent = d.resolve().parent.name if d.name == "records" else None
    return parent if parent in cfgmod.ALL_PRESET_NAMES else None


def null_spec(text: str):
    """``--null``'s value: None (none, 0), "exact", "auto" or a number K >= 1 of random
    exchanges; ConfigError for anything else."""
    t = str(text).strip().lower()
    if t in ("none", "0"):
        return None
    if t in ("exact", "auto"):
        return t
    try:
        k = int(t)
    except ValueError:
        k = None
    if k is None or k < 1:
        raise ConfigError(f"--null must be exact, auto, none or a number of random exchanges "
                          f"K >= 1, got {text!r}")
    return k


def run(args) -> int:
    """Validate both ensembles, the seeds and the output first, then run the study and write it."""
    from tiltpile.figures import same_piles as sp
    from tiltpile.paths import check_output

    if args.workers < 1:
        raise ConfigError(f"--workers must be 1 or more, got {args.workers}")
    null = null_spec(args.null)
    if args.seeds is not None and args.seeds < sp.MIN_SEEDS:
        raise ConfigError(f"--seeds must be at least {sp.MIN_SEEDS}, got {args.seeds}")
    if args.ref.resolve() == args.dir.resolve():
        raise ConfigError(f"{args.ref}: REF and DIR are the same directory")
    ref, ens = _load(args.ref), _load(args.dir)
    ref_label, label = _label(args.ref, args.ref_label, ref), _label(args.dir, args.label, ens)
    if ref_label == label:
        raise ConfigError(f"REF and DIR are both labelled {label!r}: give --ref-label or --label")
    seeds = sp.common_seeds(ref, ens)
    if args.seeds is not None:
        if len(seeds) < args.seeds:
            raise ConfigError(f"--seeds {args.seeds}: the ensembles share only {len(seeds)} seeds")
        seeds = seeds[:args.seeds]
    if len(seeds) < sp.MIN_SEEDS:
        raise ConfigError(f"{args.ref} and {args.dir} share {len(seeds)} seeds: the comparison "
                          f"needs {sp.MIN_SEEDS} or more")
    if null and len(seeds) < sp.JACKKNIFE_SEEDS:
        raise ConfigError(f"--null {args.null}: on {len(seeds)} seeds no figure number has an "
                          f"error to move by; chance's count needs {sp.JACKKNIFE_SEEDS} or more")
    if null:
        try:
            sp.null_plan(null, len(seeds))
        except ValueError as exc:
            raise ConfigError(f"--null {args.null}: {exc}") from None
    check_output(args.out / f"{sp.NAME}.json", "--out")
    ref, ens = sp.subset(ref, seeds), sp.subset(ens, seeds)
    say = None if args.quiet else (lambda line: print(f"tiltpile same-piles: {line}", file=sys.stderr,
                                                      flush=True))
    import tempfile
    with tempfile.TemporaryDirectory(prefix="tiltpile-same-piles-") as scratch:
        doc = sp.study(ref, ens, ref_label, label, progress=say, null_flips=null or 0,
                       scratch=scratch, workers=args.workers)
    path = sp.write_study(doc, args.out)
    print(f"{label} against {ref_label} on {len(seeds)} seeds: {doc['n_moved']} of "
          f"{doc['n_with_error']} figure numbers with an error moved by more than "
          f"{sp.SIGMA_LIMIT:g} standard errors ({doc['n_numbers']} numbers in all); {path}")
    if doc["null"]:
        n = doc["null"]
        how = (f"all {n['flips']} distinct exchanges" if n["method"] == "exact"
               else f"{n['flips']} random exchanges")
        print(f"  by chance ({how} of seeds' two runs): median {n['median']:g}, 95th percentile "
              f"{n['p95']:g}; p = {n['p_value']:.4f} +- {n['mc_error']:.4f}: {n['decision']}")
    for c, d in doc["pile_against_pile"]["difference"].items():
        if math.isfinite(d["mean"]):
            print(f"  {c}: {d['mean']:+.3g} [{d['ci_low']:+.3g}, {d['ci_high']:+.3g}] over {d['n']} seeds")
    return 0
