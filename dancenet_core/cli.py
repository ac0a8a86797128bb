"""`dancenet` command line: the commands of `commands/`, each imported only when it runs."""

from __future__ import annotations

import argparse
import codecs
import importlib
import io
import signal
import sys
import threading

from . import __version__
from .commands import COMMANDS
from .errors import DanceNetError


def build_parser(argv: list[str]) -> argparse.ArgumentParser:
    """The parser, with the options of the command named in `argv` (the first word that is not an option);
    the other commands are listed by name and help only."""
    parser = argparse.ArgumentParser(prog="dancenet", description="Music-driven dance generation.")
    parser.add_argument("--version", action="version", version=f"dancenet {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = next((a for a in argv if not a.startswith("-")), None)
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == chosen:
            importlib.import_module(f"{__package__}.commands.{name.replace('-', '_')}").add_arguments(p)
    return parser


def _terminate(signum: int, _frame: object) -> None:
    """SIGTERM and SIGHUP (a closed terminal) unwind like Ctrl-C, so worker processes are stopped and
    half-written files removed."""
    raise SystemExit(128 + signum)


def _names_as_they_are() -> None:
    """A file name that is not UTF-8 (Python keeps its bytes as lone surrogates) is printed as its own bytes on
    a UTF-8 terminal, as `ls` shows it, and escaped on any other, instead of stopping the command."""
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, io.TextIOWrapper):
            utf8 = codecs.lookup(stream.encoding).name == "utf-8"
            stream.reconfigure(errors="surrogateescape" if utf8 else "backslashreplace")


def main(argv: list[str] | None = None) -> int:
    if argv is None:  # the command itself, on the terminal's streams (not a caller's, e.g. a test's capture)
        _names_as_they_are()
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(argv).parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
        # SIGHUP too (none on Windows), unless ignored: `nohup dancenet ...` must outlive its terminal
        if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) is not signal.SIG_IGN:
            signal.signal(signal.SIGHUP, _terminate)
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
