"""``roar-verify``: the command-line front end.

The command line is the top layer: it alone imports typer and rich. Each
module of this package registers the sub-commands of one part of the toolkit
(``register(app)``) on top of the library; this file only wires them together
and turns user errors into located messages (no traceback).
"""

from __future__ import annotations

import errno
import os
import signal
import sys

from ..errors import RoarError

# typer and rich are imported only by the commands that use them: `roar-verify clf FILE` on a
# small program takes less time to run than typer takes to import (see docs/clf.md, start-up)
_APP = None


def _typer_app():
    """The Typer application (made once, when a command needs Typer); ``cli.app`` (module
    ``__getattr__`` below) is it with every command registered."""
    global _APP
    if _APP is None:
        import typer

        def _version(value: bool) -> None:
            if value:
                from importlib.metadata import PackageNotFoundError, version
                try:
                    v = version("roar-formal")
                except PackageNotFoundError:  # run from a source tree without installing
                    v = "unknown (not installed)"
                print(f"roar-verify (roar-formal) {v}")
                raise typer.Exit(0)

        app = typer.Typer(
            name="roar-verify",
            help="Verify ROAR robot control architectures: CLF engine, TCA proofs, state-space exploration.",
            no_args_is_help=True,
            add_completion=True,
            pretty_exceptions_enable=False,
        )

        @app.callback()
        def _root(
            show_version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                              help="Print the version and exit."),
        ) -> None:
            """Verify ROAR robot control architectures: CLF engine, TCA proofs, state-space exploration."""

        _APP = app
    return _APP


def _print_error(markup: str) -> None:
    """Print a message (rich markup) on standard error through the command line's console."""
    from .console import make_console

    make_console(stderr=True).print(markup, markup=True, soft_wrap=True)


def _escape(text: str) -> str:
    from rich.markup import escape

    return escape(text)


_PARTS = ("clf", "run", "robot", "check", "tca")  # the order commands are listed in
_registered: list[str] = []


def _register(parts=_PARTS) -> None:
    """Import the commands of the given parts (each only once); start-up imports only what
    the command being run needs (``roar-verify clf`` never loads the explorer or the robot)."""
    import importlib

    for part in _PARTS:
        if part in parts and part not in _registered:
            _registered.append(part)
            importlib.import_module(f".{part}", __package__).register(_typer_app())


def _register_all() -> None:
    _register(_PARTS)


def _register_for(args: list[str]) -> None:
    first = next((a for a in args if not a.startswith("-")), None)
    if first == "clf" and "--help" not in args and "-h" not in args:
        _register(("clf",))
    else:
        _register_all()


def __getattr__(name: str):
    # `cli.app` seen from outside has every command (tests list them)
    if name == "app":
        _register_all()
        return _typer_app()
    raise AttributeError(name)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; user errors print ``file:line:col: message`` and exit 2."""
    _exit_cleanly_on_sigterm()
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        if args[:1] == ["clf"]:  # the CLF command without Typer's start-up, when its options allow
            from .clf import fast_args, run_clf
            opts = fast_args(args[1:])
            if opts is not None:
                run_clf(**opts)
                sys.exit(0)
        _register_for(args)
        _typer_app()(args=argv, standalone_mode=True, prog_name="roar-verify")
    except RoarError as exc:
        _print_error(f"[bold red]error:[/] {_escape(exc.format())}")
        sys.exit(2)
    except KeyboardInterrupt:   # Ctrl-C where no command says more (a command that can, says what it had)
        _print_error("[yellow]interrupted[/]")
        sys.exit(130)
    except Exception as exc:  # a bug of ours, not the user's: short message, traceback on request
        if isinstance(exc, OSError) and exc.filename is not None and exc.errno in _PATH_ERRNOS:
            # a path the user gave that the system refuses (too long, a loop of links, no permission,
            # read-only, full disk) wherever a reader or writer met it: bad input, not a bug
            _print_error(f"[bold red]error:[/] {_escape(str(exc.filename))}: {_escape(exc.strerror or str(exc))}")
            sys.exit(2)
        if os.environ.get("ROAR_DEBUG"):
            raise
        _print_error(f"[bold red]internal error:[/] {_escape(type(exc).__name__)}: {_escape(str(exc))}\n"
                     "This is a bug in roar-formal; rerun with ROAR_DEBUG=1 to see the traceback.")
        sys.exit(3)


_PATH_ERRNOS = {errno.ENAMETOOLONG, errno.ELOOP, errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC,
                errno.EDQUOT, errno.ENOTDIR, errno.EISDIR, errno.ENOENT, errno.EEXIST}


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
