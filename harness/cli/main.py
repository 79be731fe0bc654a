"""The `harness` command's door: the command run in a child process, whose exit status the harness
alone chooses (0 every gate passed, 1 a gate failed, 2 bad input, 3 an internal error, 130 Ctrl-C)."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import traceback
from pathlib import Path

from harness.base.tomlio import InputError
from harness.cli import run as run_command
from harness.cli.common import DEFAULT_SCENARIO, EXIT_BAD_INPUT, EXIT_INTERNAL, write_file_atomically
from harness.cli.parser import parser
from harness.cli.project import cmd_audit, cmd_init, cmd_list
from harness.cli.results import cmd_compare, cmd_gate, cmd_report
from harness.cli.run import cmd_run
from harness.cli.sweep import cmd_excite, cmd_sweep
from harness.runner.ci import error_summary, error_xml

# each command imports what it needs when it runs
COMMANDS = {"run": cmd_run, "report": cmd_report, "gate": cmd_gate, "compare": cmd_compare, "sweep": cmd_sweep,
            "excite": cmd_excite, "list": cmd_list, "init": cmd_init, "audit": cmd_audit}


class _Stdout:
    """Standard output that goes quiet once its reader has gone (`harness list | head -1`): a
    broken pipe is not a verdict, so the command runs to its end and exits with its own status."""

    def __init__(self, stream):
        self.stream, self.gone = stream, False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                return self.stream.write(text)
            except BrokenPipeError:
                self._gone()
        return len(text)

    def flush(self) -> None:
        if not self.gone:
            try:
                self.stream.flush()
            except BrokenPipeError:
                self._gone()

    def _gone(self) -> None:
        self.gone = True
        try:  # what is still buffered goes nowhere, also when the interpreter flushes at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), self.stream.fileno())
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


def _no_verdict(args: argparse.Namespace, kind: str, message: str) -> None:
    """Bad input or an internal error: the CI files asked for still say so, as one test case with
    an error (harness/runner/ci.py). Nothing is written where the CI file itself is the fault."""
    given = next((v for v in (getattr(args, k, None) for k in ("scenarios", "results", "scenario", "candidate")) if v),
                 [DEFAULT_SCENARIO] if args.command == "run" else [f"harness {args.command}"])
    name = " ".join(str(s) for s in (given if isinstance(given, list) else [given]))
    for attr, text in (("junit_xml", error_xml), ("summary", error_summary)):
        path = getattr(args, attr, None)
        if path is not None:
            try:
                write_file_atomically(path, text(name, kind, message))
            except OSError:
                pass


def _origin(exc: BaseException) -> str:
    where = traceback.extract_tb(exc.__traceback__)
    return f" (at {Path(where[-1].filename).name}:{where[-1].lineno})" if where else ""


def main(argv: list[str] | None = None) -> int:
    """The command, in this process. Only the harness chooses the exit status: 0 every gate passed,
    1 a gate failed, 2 bad input (plugin code that raises anything, SystemExit and KeyboardInterrupt
    included, is bad input), 3 an internal error, 130 the user's Ctrl-C."""
    from harness.base.plugins import PluginError, interrupted_by_user, user_interrupts

    # the command draws nothing on screen: MuJoCo's OpenGL contexts (glfw, about 0.13 s of its import)
    # are not loaded unless the environment asks for them (MUJOCO_GL set beforehand is kept)
    os.environ.setdefault("MUJOCO_GL", "disable")
    args = parser().parse_args(argv)
    # where to write, fixed now: plugin code may change directory
    for attr in ("out", "junit_xml", "summary", "figures"):
        if getattr(args, attr, None) is not None:
            setattr(args, attr, Path(os.path.abspath(getattr(args, attr))))
    args.reports = Path(os.path.abspath("reports"))  # the default output folder's parent
    stdout, sys.stdout = sys.stdout, _Stdout(sys.stdout)
    status, kind, message = EXIT_INTERNAL, "internal error", ""
    try:
        with user_interrupts():
            status = COMMANDS[args.command](args)
    except InputError as exc:
        status, kind, message = EXIT_BAD_INPUT, "bad input", exc.one_line()
    except PluginError as exc:
        status, kind, message = EXIT_BAD_INPUT, "bad input", f"plugin {exc}"
    except KeyboardInterrupt as exc:
        if interrupted_by_user():
            print("harness: interrupted", file=sys.stderr)
            status = 130
        else:  # raised by code, not by the user: a plugin's, reached outside its guard
            status, kind = EXIT_BAD_INPUT, "bad input"
            message = f"KeyboardInterrupt raised by code, not by the user{_origin(exc)}"
    except SystemExit as exc:  # the harness never calls sys.exit inside a command: plugin code did
        status, kind = EXIT_BAD_INPUT, "bad input"
        message = f"sys.exit({exc.code!r}) called by code the harness ran{_origin(exc)}: it does not end the run"
    except Exception as exc:
        if args.debug:
            traceback.print_exc()
        message = (f"internal error: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                   f"{_origin(exc)}{'' if args.debug else '; --debug shows the traceback'}")
    finally:
        sys.stdout.flush()
        sys.stdout = stdout
    if message:
        print(f"harness: {'error: ' if kind == 'bad input' else ''}{message}", file=sys.stderr)
        _no_verdict(args, kind, message)
    return status


def entry() -> None:
    """The `harness` command. The command runs in a child process and this one chooses the exit
    status: a child that ends without handing back its status (plugin code calling os._exit, or
    crashing the interpreter) is an internal error, exit 3, with the CI files still written.
    Where processes cannot be forked, it runs here."""
    argv = sys.argv[1:]
    if not hasattr(os, "fork"):
        sys.exit(main(argv))
    args = parser().parse_args(argv)  # usage errors: exit 2 here, before anything is started
    sys.stdout.flush()
    sys.stderr.flush()
    from harness.cli.started import STARTED

    run_command.BORN = STARTED  # the harness's start, on the clock the child keeps (perf_counter is monotonic)
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: the command
        os.close(read_end)
        status = EXIT_INTERNAL
        run_command.ENDS_WITH_COMMAND = True
        try:
            status = main(argv)
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (OSError, ValueError):
                    pass
            os.write(write_end, bytes([status]))
            os._exit(status)
    os.close(write_end)
    # Ctrl-C and SIGTERM are passed on to the child, which unwinds and answers 130 (a second one,
    # from the terminal to the whole process group, finds it already unwinding)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda signum, frame: os.kill(pid, signum))
    _, wait_status = os.waitpid(pid, 0)
    os.set_blocking(read_end, False)  # processes the child started may hold the pipe open: read what is there
    try:
        handed = os.read(read_end, 1)
    except BlockingIOError:
        handed = b""
    os.close(read_end)
    if handed:
        _leave(handed[0])
    if os.WIFSIGNALED(wait_status) and os.WTERMSIG(wait_status) in (signal.SIGINT, signal.SIGTERM):
        print("harness: interrupted", file=sys.stderr)
        _leave(130)
    how = (f"killed by signal {signal.Signals(os.WTERMSIG(wait_status)).name}" if os.WIFSIGNALED(wait_status)
           else f"exit status {os.WEXITSTATUS(wait_status)}")
    message = (f"internal error: the command ended without a verdict ({how}): code it ran (a plugin?) ended the "
               "process or crashed it")
    print(f"harness: {message}", file=sys.stderr)
    _no_verdict(args, "internal error", message)
    _leave(EXIT_INTERNAL)


def _leave(status: int) -> None:
    """The waiting process ends with the child's verdict: its output flushed, and without the
    interpreter's teardown of the modules it imported (numpy's among them: 10 to 15 ms), since it
    holds nothing else to release."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


if __name__ == "__main__":  # pragma: no cover
    entry()
