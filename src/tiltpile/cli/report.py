"""``tiltpile report``: the reproduction reports (claims against our numbers) from the figures' JSON.

Without ``--figures``: the main report, ``paper/REPRODUCTION.md``, which leads with the paper's
scale and sets every axis measured beside it (:mod:`tiltpile.report.main`); with ``--studies``,
every side study in full, once (``paper/STUDIES.md``). With ``--figures DIR``: the report of one
scale's figures (its claims and its judges' notes), e.g. ``figures/paper/REPRODUCTION.md``.
"""

from __future__ import annotations

MAIN_OUT, STUDIES_OUT = "paper/REPRODUCTION.md", "paper/STUDIES.md"


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="write the reproduction report from the figures' JSON",
                       description="Without --figures: the main report (paper/REPRODUCTION.md) "
                                   "from every scale's figures under --root; with --studies the "
                                   "side studies in full (paper/STUDIES.md). With --figures DIR: "
                                   "the report of that one scale's figures.")
    p.add_argument("--figures", help="one scale's directory of fig*.json: write its own report "
                                     "(--out required)")
    p.add_argument("--root", default="figures",
                   help="the figures root of the main report: the default scale's figures, the "
                        "other scales in ROOT/<preset>/ (default figures)")
    p.add_argument("--studies", action="store_true",
                   help=f"write the side studies in full instead of the main report (default "
                        f"--out {STUDIES_OUT})")
    p.add_argument("--out", help=f"Markdown file to write (main report: default {MAIN_OUT})")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.cli._common import ConfigError

    if args.figures is None:
        if args.studies:
            from tiltpile.report import write_studies

            print(write_studies(args.root, args.out or STUDIES_OUT))
            return 0
        from tiltpile.report.main import write_main_report

        print(write_main_report(args.root, args.out or MAIN_OUT))
        return 0
    if args.studies:
        raise ConfigError("--studies reads every scale under --root: give --root, not --figures")
    if not args.out:
        raise ConfigError("--figures DIR: give --out FILE, the scale's report (e.g. DIR/REPRODUCTION.md)")
    from tiltpile.report import write_report

    print(write_report(args.figures, args.out))
    return 0
