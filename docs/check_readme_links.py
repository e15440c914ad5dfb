"""Check that every relative link and image of ``README.md`` points to a file of the repository.

MkDocs checks the manual's own links (``--strict``); the README lives outside it and is what a code
host shows first, so ``make docs`` runs this too. Links to a heading (``file.md#anchor``) are
checked for the file only. Exit status 1 lists every broken link with its line.

Run from the repository root: ``python docs/check_readme_links.py [FILE.md ...]``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: ``[text](target)`` and ``![alt](target)``; the target ends at whitespace or ``)``.
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
#: Targets that are not files of this repository.
EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|#|//)", re.IGNORECASE)


def broken_links(md: Path) -> list[str]:
    """``"file:line: target"`` for every relative link of ``md`` whose file does not exist."""
    problems = []
    in_code = False
    for number, line in enumerate(md.read_text(encoding="utf-8").splitlines(), start=1):
        if line.lstrip().startswith("```"):
            in_code = not in_code
            continue
        if in_code:
            continue
        for target in LINK.findall(line):
            if EXTERNAL.match(target):
                continue
            path = (md.parent / target.split("#", 1)[0]).resolve()
            if not path.exists():
                problems.append(f"{md.relative_to(REPO)}:{number}: {target}")
    return problems


def main(argv: list[str] | None = None) -> int:
    files = [Path(a).resolve() for a in (argv if argv is not None else sys.argv[1:])] or [REPO / "README.md"]
    problems = [p for f in files for p in broken_links(f)]
    for p in problems:
        print(f"broken link: {p}", file=sys.stderr)
    if not problems:
        print(f"{', '.join(str(f.relative_to(REPO)) for f in files)}: every relative link resolves")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
