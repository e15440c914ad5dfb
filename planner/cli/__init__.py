"""``cctmill`` command line: a thin shell over library calls, one module per command.

Each command module has ``register(sub)``, which adds its parser and sets ``run``: it parses, calls
one library function, prints its result. Units at this edge carry their names (``--feed-mm-s``,
``--ae-mm``, ``--joints-deg``); everything is converted to SI before it reaches the library.
Errors a user can cause print one line ``cctmill <command>: error: ...`` and exit with status 2;
no traceback. Every option that names an output is added with :func:`~planner.cli._common.add_output`
and checked before the command runs.
"""

from __future__ import annotations

import importlib
import re
import sys
from collections.abc import Sequence

from models.errors import CctmillError
from planner.cli._common import Parser, check_outputs

__all__ = ["COMMAND_MODULES", "build_parser", "main"]

#: The command modules, in the order ``cctmill --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "planner.cli.analyze", "planner.cli.inspect", "planner.cli.demo", "planner.cli.export",
    "planner.cli.calibrate",
    "planner.cli.library",
    "planner.cli.place", "planner.cli.plan", "planner.cli.robot_sim", "planner.cli.simulate",
    "planner.cli.supervise",
    "planner.cli.testcuts")


def build_parser() -> Parser:
    """The ``cctmill`` argument parser, every command registered."""
    parser = Parser(prog="cctmill", description="Planner and supervisor for robotic milling.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _join_negative_values(argv: Sequence[str]) -> list[str]:
    """``--joints-deg -96.4,-29.3,...`` → ``--joints-deg=-96.4,...``.

    argparse takes a value that starts with ``-`` and is not a plain number for an option; no cctmill
    option starts with a digit, so a ``-`` followed by a digit or ``.`` is always a value.
    """
    out: list[str] = []
    for tok in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and re.match(r"^-[0-9.]", tok)):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cctmill`` console script."""
    parser = build_parser()
    args = parser.parse_args(_join_negative_values(sys.argv[1:] if argv is None else argv))
    try:
        check_outputs(args)     # before the work: a long plan is not lost to a typo in -o
        return int(args.run(args))
    except CctmillError as e:
        from planner._progress import close_all

        close_all()             # a bar the error interrupted: the message gets its own line
        print(f"cctmill {args.command}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
