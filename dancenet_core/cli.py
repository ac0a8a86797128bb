"""`dancenet` command line. Each subcommand registers its parser here and runs lazily."""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
from collections.abc import Callable

from .errors import DanceNetError

Handler = Callable[[argparse.Namespace], int]

# Modules that define `add_parser(subparsers)`, which registers a subcommand and sets its `handler`
# with `set_defaults(handler=...)`. Keep imports of heavy libraries inside the handlers.
_COMMAND_MODULES: list[str] = ["generate_cmd", "data.build", "analyze", "render_cmd", "comparison"]


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dancenet", description="Music-driven dance generation.")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in _COMMAND_MODULES:
        importlib.import_module(f"dancenet_core.{name}").add_parser(sub)
    return parser


def _terminate(signum: int, _frame: object) -> None:
    """SIGTERM unwinds like Ctrl-C, so worker processes are stopped and half-written files removed."""
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(args.handler(args) or 0)
    except DanceNetError as e:
        print(f"dancenet: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dancenet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
