"""``ctlab``'s entry (scripts/ctlab.py, the background job): parse, fill the job's defaults,
run the command; bad input is one line and exit status 2, a cancel exit status 130."""

from __future__ import annotations

import sys
from typing import NoReturn

from .options import fill_defaults
from .parser import build_parser, join_negative_values
from .. import signals
from ...core.errors import Cancelled, UserError

EXIT_BAD_INPUT = 2
EXIT_CANCELLED = 130


def main(argv_=None) -> int:
    parser = build_parser()
    argv_ = sys.argv[1:] if argv_ is None else list(argv_)
    try:
        try:
            args = parser.parse_args(join_negative_values(argv_))
        except SystemExit as exc:  # --help
            return EXIT_BAD_INPUT if exc.code else 0
        if args.command != "plan":  # plan's job is its argument: it fills them itself
            fill_defaults(args, "parity" if getattr(args, "parity", False) else "matrix")
        args.func(args)
    except UserError as exc:
        signals.yield_to_cancel()
        one_line = " ".join(str(exc).split())  # a library's message may hold newlines
        print(f"ctlab: error: {one_line}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except (Cancelled, KeyboardInterrupt):
        signals.yield_to_cancel()  # a signal's cancel prints its own line
        print("ctlab: cancelled; finished outputs are kept", file=sys.stderr, flush=True)
        return EXIT_CANCELLED
    return 0


def run_and_exit(argv_) -> NoReturn:
    """A ctlab process's whole run (scripts/ctlab.py, the add-on's background job): ``main``
    and its exit status. While a signal's cancel is under way (jobs/signals.py) neither an
    error, which its removals may cause, nor the end of the work decides the status: the
    watcher's 130 does."""
    try:
        code = main(argv_)
    except BaseException:
        signals.yield_to_cancel()
        raise
    signals.yield_to_cancel()
    sys.stdout.flush()
    sys.exit(code)
