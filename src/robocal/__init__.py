"""robocal: calibrate robots.

Joint zero offsets for Robstride, Feetech and Dynamixel joints, LeRobot calibration files and
normalisation, and Universal Robots kinematic calibration correction. The math lives in
:mod:`robocal.core` (pure numpy); hardware, files and the CLI are layered around it.
"""

# no `from __future__` import here: it is a module of its own to load, a window before the handlers below
import os as _os  # already loaded by Python's start-up (site): costs nothing
import sys as _sys


def _program_startup_handlers() -> None:
    """When this process is the ``robocal`` program: a signal now prints one line and exits ``128 + signum``.

    The very first code of the program (the console script and ``python -m robocal`` both import this package
    first), ahead of every other import, so a Ctrl-C or ``kill`` in the rest of the start-up never shows a
    traceback; :mod:`robocal.cli.entry` takes over with the same behaviour. Nothing happens for a program that
    merely imports robocal. Uses the builtin ``_signal`` (``signal`` would import ``enum`` first).
    """
    argv0 = _sys.argv[0] if _sys.argv else ""
    # python [options] -m robocal ...: argv[0] is "-m" until runpy has found the module
    orig = list(getattr(_sys, "orig_argv", ()))
    as_module = argv0 == "-m" and "-m" in orig and orig[orig.index("-m") + 1 :][:1] == ["robocal"]
    if not as_module and _os.path.basename(argv0) not in ("robocal", "robocal.exe"):
        return
    sig = __import__("_signal")
    lines = {
        getattr(sig, name): f"error: interrupted{by}\n".encode()
        for name, by in (
            ("SIGINT", ""),
            ("SIGTERM", " by SIGTERM"),
            ("SIGHUP", " by SIGHUP"),
            ("SIGQUIT", " by SIGQUIT"),
        )
        if hasattr(sig, name)
    }

    def exit_now(signum: int, frame: object) -> None:
        try:
            _os.write(2, lines[signum])
        finally:
            _os._exit(128 + signum)

    for signum in lines:
        try:
            if sig.getsignal(signum) != sig.SIG_IGN:  # an ignored signal stays ignored (nohup)
                sig.signal(signum, exit_now)
        except (OSError, ValueError):  # not the main thread
            continue


_program_startup_handlers()

from .errors import CalibError as CalibError  # noqa: E402 - after the handlers, on purpose

__all__ = ["CalibError", "__version__"]


def __getattr__(name: str) -> str:
    """``robocal.__version__``, looked up on first use (the lookup is slow; ``robocal`` starts without it)."""
    if name != "__version__":
        raise AttributeError(f"module 'robocal' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("robocal")
    except PackageNotFoundError:  # running from a source tree without installation
        found = "0.0.0+src"
    globals()["__version__"] = found
    return found
