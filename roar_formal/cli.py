"""``roar-verify``: the command-line front end.

Each part of the toolkit contributes its sub-commands through a
``register(app)`` function in its own ``commands`` module; this file only
wires them together and turns user errors into located messages (no traceback).
"""

from __future__ import annotations

import os
import signal
import sys

import typer
from rich.markup import escape

from .console import make_console
from .errors import RoarError

app = typer.Typer(
    name="roar-verify",
    help="Verify ROAR robot control architectures: CLF engine, TCA proofs, state-space exploration.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

err_console = make_console(stderr=True)


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version
        try:
            v = version("roar-formal")
        except PackageNotFoundError:  # run from a source tree without installing
            v = "unknown (not installed)"
        print(f"roar-verify (roar-formal) {v}")
        raise typer.Exit(0)


@app.callback()
def _root(
    show_version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                      help="Print the version and exit."),
) -> None:
    """Verify ROAR robot control architectures: CLF engine, TCA proofs, state-space exploration."""


def _register_all() -> None:
    from .clf import commands as clf_commands
    from .explore import commands as explore_commands
    from .roar import commands as roar_commands
    from .robot import commands as robot_commands
    from .tca import commands as tca_commands

    for module in (clf_commands, roar_commands, robot_commands, explore_commands, tca_commands):
        module.register(app)


_register_all()


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; user errors print ``file:line:col: message`` and exit 2."""
    _exit_cleanly_on_sigterm()
    try:
        app(args=argv, standalone_mode=True)
    except RoarError as exc:
        err_console.print(f"[bold red]error:[/] {escape(exc.format())}", markup=True, soft_wrap=True)
        sys.exit(2)
    except Exception as exc:  # a bug of ours, not the user's: short message, traceback on request
        if os.environ.get("ROAR_DEBUG"):
            raise
        err_console.print(f"[bold red]internal error:[/] {escape(type(exc).__name__)}: {escape(str(exc))}\n"
                          "This is a bug in roar-formal; rerun with ROAR_DEBUG=1 to see the traceback.",
                          markup=True, soft_wrap=True)
        sys.exit(3)


def _exit_cleanly_on_sigterm() -> None:
    """SIGTERM (a CI timeout, ``kill``) unwinds like Ctrl-C: files being written are removed
    (``trace.format.write_atomic``) instead of being left behind half-done."""
    def stop(signum, frame):  # pragma: no cover - exercised through a subprocess
        raise SystemExit(128 + signum)

    try:
        if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, stop)
    except (ValueError, OSError, AttributeError):  # not the main thread, or no SIGTERM here
        pass


if __name__ == "__main__":  # pragma: no cover
    main()
