"""Regenerate the job file reference in ``docs/job.md`` from the schema in ``planner/job.py``.

The block between the marker lines ``<!-- job-reference:start -->`` and ``<!-- job-reference:end -->``
is replaced by the output of :func:`planner.job.reference_markdown` (with a blank line after the start
marker, so Markdown does not read the first table as part of the comment); the text around it is
written by hand. ``make docs`` runs this before building the manual; the file is committed.

Run from the repository root: ``python docs/gen_job_reference.py [--check]``. With ``--check`` the
file is not written and the exit status is 1 when it is out of date.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from planner.job import reference_markdown  # noqa: E402

PAGE = REPO / "docs" / "job.md"
START = "<!-- job-reference:start -->"
END = "<!-- job-reference:end -->"


def regenerate(text: str, reference: str) -> str:
    """``text`` with the marked block replaced by ``reference``; raises ValueError without markers."""
    i, j = text.find(START), text.find(END)
    if i < 0 or j < 0 or j < i:
        raise ValueError(f"{PAGE.name}: need the marker lines {START} and {END}, in that order")
    return text[:i] + START + "\n\n" + reference.rstrip("\n") + "\n\n" + text[j:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="only report whether docs/job.md is current")
    args = ap.parse_args(argv)
    old = PAGE.read_text(encoding="utf-8")
    try:
        new = regenerate(old, reference_markdown())
    except ValueError as e:
        print(f"gen_job_reference: error: {e}", file=sys.stderr)
        return 2
    rel = PAGE.relative_to(REPO)
    if new == old:
        print(f"{rel}: job reference up to date")
        return 0
    if args.check:
        print(f"{rel}: job reference out of date (run: make docs)", file=sys.stderr)
        return 1
    tmp = PAGE.with_name(f".{PAGE.name}.tmp")
    tmp.write_text(new, encoding="utf-8")
    tmp.replace(PAGE)
    print(f"{rel}: job reference regenerated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
