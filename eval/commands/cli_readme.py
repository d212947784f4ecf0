"""``python -m eval.commands.cli_readme [--check] [README]``: the README's generated blocks rendered from the committed
results (:mod:`eval.reports.readme`). Exit 0: written (or, with ``--check``, every block matches the files); 1: with
``--check``, a block differs; 2: a missing or malformed README or results file (one line)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from eval.reports.readme import ROOT, ReadmeError, blocks_of, changed_blocks, render_readme


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the README's generated blocks from the committed results, or check them; the exit status."""
    parser = argparse.ArgumentParser(prog="python -m eval.commands.cli_readme", description=__doc__.split("\n")[0])
    parser.add_argument("readme", nargs="?", type=Path, default=ROOT / "README.md")
    parser.add_argument("--check", action="store_true", help="exit 1 when a block differs from the files")
    args = parser.parse_args(argv)
    try:
        text = args.readme.read_text(encoding="utf-8")
        root = args.readme.resolve().parent
        rendered = render_readme(text, root)
        changed = changed_blocks(text, root) if args.check else []
    except (OSError, ReadmeError) as exc:
        print(f"readme: error: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if rendered != text:
            print(f"{args.readme}: generated blocks differ from the results files ({', '.join(changed) or 'layout'}); "
                  "run: python -m eval.commands.cli_readme", file=sys.stderr)
            return 1
        print(f"{args.readme}: every generated block matches the results files")
        return 0
    args.readme.write_text(rendered, encoding="utf-8")
    print(f"wrote {args.readme} ({len(blocks_of(rendered))} generated blocks)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
