"""What every physlab command line shares: one-line errors with exit code 2.

A user's mistake (a bad flag value, a missing or unreadable file, a parameter the library
rejects) prints exactly one line ``<prog>: error: <what is wrong and what to do>`` on stderr
and exits with status 2; ``--debug`` shows the traceback instead.
"""
from __future__ import annotations

import argparse
import functools
import sys

__all__ = ["Parser", "run", "guard", "run_subcommand", "stop_like_ctrl_c"]


class Parser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` whose usage errors are one line (no usage dump), with
    a ``--debug`` flag, and whose help keeps the example layout of its epilog."""

    def __init__(self, *args, root_prog=None, **kwargs):
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)
        self.root_prog = root_prog or self.prog
        # A subcommand's parser ("physlab animate") must not reset a --debug given before it.
        self.add_argument("--debug", action="store_true",
                          default=argparse.SUPPRESS if root_prog else False,
                          help="show the full traceback of an error")

    def add_subparsers(self, **kwargs):
        kwargs.setdefault("parser_class", functools.partial(Parser, root_prog=self.prog))
        return super().add_subparsers(**kwargs)

    def error(self, message):
        self.exit(2, f"{self.root_prog}: error: {message} (see {self.prog} --help)\n")

    def rename(self, prog):
        """Show this parser as the subcommand ``prog`` (e.g. ``"physlab train motion"``): usage,
        help and the epilog's ``%(prog)s`` examples name it, and usage errors start with the
        command's name (``physlab: error: ...``). Returns the parser."""
        self.prog, self.root_prog = prog, prog.split()[0]
        return self


def run(prog, func, debug=False):
    """Call ``func()``; on an exception print ``prog: error: ...`` (one line) and return 2,
    unless ``debug`` (then re-raise). Ctrl-C returns 130. Otherwise returns func's result
    (0 if it returns None)."""
    try:
        out = func()
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - a command line turns every failure into a line
        if debug:
            raise
        msg = " ".join(str(e).split()) or "(no message)"
        known = (ValueError, TypeError, OSError, RuntimeError)
        what = msg if isinstance(e, known) else f"{type(e).__name__}: {msg}"
        print(f"{prog}: error: {what}" + ("" if isinstance(e, known) else
                                          " (run with --debug for the traceback)"),
              file=sys.stderr)
        return 2
    return 0 if out is None else out


def stop_like_ctrl_c():
    """Make SIGTERM, and a SIGINT that a non-interactive shell set to be ignored (``cmd &``),
    stop the process the way Ctrl-C does: :class:`KeyboardInterrupt` is raised, so a training
    loop writes its checkpoint and the same command resumes it. For long-running commands;
    only the main thread can install signal handlers (elsewhere this does nothing)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt(signal.Signals(signum).name)

    signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)


def run_subcommand(prog, parser, main, argv):
    """Run a module's command line ``main(argv)`` as the subcommand ``prog`` of a bigger
    command, e.g. ``physlab train motion`` for ``python -m physlab.motion.train``.

    ``parser`` is that module's own parser (``_parser()``, prog ``python -m ...``): renamed by
    :meth:`Parser.rename`, it parses ``argv`` first, so ``--help`` and usage errors name
    ``prog`` and exit here (0, or 2 with one line); ``main`` then parses the same, valid
    arguments again and does the work. Returns ``main``'s result."""
    parser.rename(prog).parse_args(argv)
    return main(argv)


def guard(prog, main, argv=None):
    """Run a module's ``main(argv)`` as a command: one-line errors (exit 2) unless
    ``--debug`` is among the arguments; a non-integer result counts as success (0)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    status = run(prog, lambda: main(argv), debug="--debug" in argv)
    return status if isinstance(status, int) else 0
