"""The `rc1` command: a module per command (its options beside its body), shared option types in options.py.
main() only parses arguments and calls the library."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

from ..config import Rc1Error
from ..engine import ENGINES, engine_for
from .compare import add_compare, cmd_compare
from .compensate import add_compensate, cmd_compensate
from .design import add_design, cmd_design
from .diagnose import add_diagnose, cmd_diagnose
from .effects import add_effects, cmd_effects
from .identify import add_identify, cmd_identify
from .options import Parser, check_outputs
from .reproduce import add_reproduce, cmd_reproduce
from .run import add_run, cmd_run
from .sweep import add_sweep, cmd_sweep
from .synthesize import add_synthesize, cmd_synthesize


def make_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="rc1", description="Simulate the RC1 wheeled snake robot (Drake).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add in (
        add_run,
        add_synthesize,
        add_compare,
        add_sweep,
        add_identify,
        add_compensate,
        add_effects,
        add_diagnose,
        add_design,
        add_reproduce,
    ):
        add(sub)
    # Every simulating command picks its engine.
    for name, command in sub.choices.items():
        if name == "effects":
            continue
        default = "drake" if name == "run" else "compiled"
        command.add_argument(
            "--engine",
            choices=ENGINES,
            default=default,
            help=f"drake (the Diagram, the model of record) or compiled (its numba twin; "
            f"tests/test_engine.py) (default: {default})",
        )
    return parser


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    args.command_line = "rc1 " + " ".join(sys.argv[1:] if argv is None else argv)
    args.kept = []  # what a long command has written so far: named if it fails later
    engine = getattr(args, "engine", None)
    with engine_for(engine) if engine else contextlib.nullcontext():  # batch work and its workers follow it
        return _dispatch(args)


def _dispatch(args) -> int:
    """The parsed command, its errors as one line (an unforeseen one's traceback in a log)."""
    try:
        check_outputs(args)
        return {
            "run": cmd_run,
            "synthesize": cmd_synthesize,
            "compare": cmd_compare,
            "sweep": cmd_sweep,
            "identify": cmd_identify,
            "compensate": cmd_compensate,
            "effects": cmd_effects,
            "diagnose": cmd_diagnose,
            "design": cmd_design,
            "reproduce": cmd_reproduce,
        }[args.command](args)
    except Rc1Error as e:
        print(f"rc1 {args.command}: error: {e}{_kept(args)}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"rc1 {args.command}: error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rc1 {args.command}: interrupted{_kept_and_resume(args)}", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - anything unforeseen: one line, the traceback in a log
        log = _write_log(args)
        print(
            f"rc1 {args.command}: internal error: {type(e).__name__}: {_first_line(e)}{_kept_and_resume(args)}; "
            f"full log: {log}",
            file=sys.stderr,
        )
        return 1


def _first_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text if len(text) <= 200 else text[:197] + "..."


def _kept(args) -> str:
    """What a long command had written before it stopped."""
    return f"; kept: {', '.join(args.kept)}" if args.kept else ""


def _kept_and_resume(args) -> str:
    """What the command had written, and how to go on from its checkpoint."""
    kept = _kept(args)
    resumes = args.command in ("identify", "diagnose", "sweep")
    return kept + ("; run the same command again to resume from its checkpoint" if resumes else "")


def _write_log(args) -> Path:
    """The traceback of the exception being handled and the command line, in out/logs (else the temporary folder)."""
    import traceback

    text = f"{args.command_line}\n{time.strftime('%Y-%m-%d %H:%M:%S')}\n\n{traceback.format_exc()}"
    name = f"rc1-{args.command}-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.log"
    for folder in (Path("out") / "logs", Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)
            return folder / name
        except OSError:
            continue
    return Path("(no log: nowhere to write it)")
