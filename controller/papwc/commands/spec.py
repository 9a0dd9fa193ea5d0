"""``papwc spec``: two batteries' spec figures side by side (tuned and out of sample)."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = ("set two batteries' spec.csv side by side: the figures on the files a controller was "
        "tuned on and on the same files with other seeds")

EPILOG = """\
examples:
  papwc battery scenarios/realism_mc.toml scenarios/realism_mc_lugre.toml --out results/mc
  papwc battery scenarios/realism_mc.toml scenarios/realism_mc_lugre.toml \\
      --seed-offset 1000 --out results/mc_oos
  papwc spec results/mc results/mc_oos                    # the table on stdout
  papwc spec results/mc results/mc_oos --out results/cmp  # and spec_compare.csv, .md there

A battery of the second folder is matched to one of the first by its name (less a
twin file's suffix _fresh or _oos), then by case and controller. exit code: 0, or 2
if a spec.csv is missing or not one papwc battery wrote.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``papwc spec`` to its subparser."""
    parser.add_argument("tuned", type=Path, metavar="TUNED",
                        help="the battery folder (or its spec.csv) the controllers were tuned on")
    parser.add_argument("other", type=Path, metavar="OTHER",
                        help="the battery folder (or its spec.csv) on other seeds")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="also write spec_compare.csv and spec_compare.md into DIR")


def run(args: argparse.Namespace) -> int:
    """Print (and with --out write) the side-by-side table; 0."""
    from papwc.battery.spec import COMPARE_COLUMNS, compare_markdown, compare_rows, read_spec

    rows = compare_rows(read_spec(args.tuned), read_spec(args.other))
    text = compare_markdown(rows, str(args.tuned), str(args.other))
    if args.out is not None:
        from papwc.output_files import make_folder, write_rows, write_text

        make_folder(args.out)
        write_rows(args.out / "spec_compare.csv", rows, COMPARE_COLUMNS)
        write_text(args.out / "spec_compare.md", text)
    print(text)
    return 0
