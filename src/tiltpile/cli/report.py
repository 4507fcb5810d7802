"""``tiltpile report``: the reproduction report (claims against our numbers) from the figures' JSON."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="write the reproduction report from the figures' JSON")
    p.add_argument("--figures", default="figures", help="directory with fig*.json (default figures)")
    p.add_argument("--out", default="paper/REPRODUCTION.md", help="Markdown file to write")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.report import write_report

    print(write_report(args.figures, args.out))
    return 0
