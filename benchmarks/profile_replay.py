"""Where a compiled replay's time goes: a profile of numba's JIT code by name (docs/findings.md 2026-11-29 (24)).

    python benchmarks/profile_replay.py [--trial j7_1] [--seconds 20] [--refcounts 60000]

A child process replays a shipped trial in a loop, its kernels compiled afresh (a temporary NUMBA_CACHE_DIR: code
loaded from the cache has no module to name its functions) and their addresses written as a perf map
(/tmp/perf-PID.map), so `perf record` names the JIT code's samples. Printed: the flat profile (share of samples per
function), then, with --refcounts N, who calls numba's reference counting and allocation: gdb breaks on NRT_incref,
NRT_decref and NRT_MemInfo_alloc_aligned N times, reading each call's return address, and counts them per calling
function. Needs perf and gdb (Linux); a few minutes,
most of it compiling.
"""

import argparse
import collections
import multiprocessing
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GDB_SCRIPT = """
import collections, gdb
counts, limit = collections.Counter(), int(gdb.parse_and_eval("$limit"))
class Caller(gdb.Breakpoint):
    def stop(self):
        sp = int(gdb.parse_and_eval("$sp"))
        counts[(self.location, int(gdb.parse_and_eval(f"*(unsigned long*){sp}")))] += 1
        return sum(counts.values()) >= limit
for name in ("NRT_incref", "NRT_decref", "NRT_MemInfo_alloc_aligned"):
    Caller(name)
gdb.execute("continue")
with open(gdb.parse_and_eval("$out").string(), "w") as f:
    f.writelines(f"{loc} {ret} {n}\\n" for (loc, ret), n in counts.items())
gdb.execute("detach")
"""


def replay_forever(trial: str, ready) -> None:
    """Replay `trial` in a loop after writing the perf map of the replay's compiled library."""
    from rc1_drake.config import REPO_ROOT, Scenario
    from rc1_drake.engine import run
    from rc1_drake.measurements import load_trial
    from rc1_drake.replay import Replayer

    friction = Scenario().friction
    replayer = Replayer(load_trial(REPO_ROOT / "data" / "paper_campaign" / f"{trial}.json"), engine="compiled")
    replayer.run(friction)
    functions = sorted(
        (cres.library.get_pointer_to_function(f.name), f.name)
        for cres in run.advance_run.overloads.values()
        for f in cres.library._final_module.functions  # numba's own module: the only place the names are
        if not f.is_declaration
    )
    functions = [(address, name) for address, name in functions if address]
    with open(f"/tmp/perf-{os.getpid()}.map", "w") as f:
        for (address, name), (after, _) in zip(functions, [*functions[1:], (functions[-1][0] + 4096, "")], strict=True):
            f.write(f"{address:x} {after - address:x} {name}\n")
    ready.set()
    while True:
        replayer.run(friction)


def readable(symbol: str) -> str:
    """A mangled JIT name (_ZN9rc1_drake8friction13friction_stepB...) as its last two parts, friction.friction_step."""
    if not symbol.startswith("_ZN"):
        return symbol
    names, at = [], 3
    while at < len(symbol) and symbol[at].isdigit():
        digits = re.match(r"\d+", symbol[at:])[0]
        at += len(digits)
        names.append(symbol[at : at + int(digits)])
        at += int(digits)
    return ".".join(names[-2:]) or symbol


def perf_profile(pid: int, seconds: float) -> str:
    with tempfile.TemporaryDirectory() as folder:
        data = Path(folder) / "perf.data"
        subprocess.run(["perf", "record", "-q", "-F", "2000", "-p", str(pid), "-o", data, "--", "sleep", str(seconds)])
        report = subprocess.run(
            ["perf", "report", "-i", data, "--no-children", "--sort", "sym", "--stdio"], capture_output=True, text=True
        ).stdout
    rows = [re.match(r"\s*([\d.]+)%\s+\[\.\]\s+(\S+)", line) for line in report.splitlines()]
    return "\n".join(f"{float(m[1]):6.2f}%  {readable(m[2])}" for m in rows if m and float(m[1]) >= 0.3)


def callers(pid: int, limit: int) -> str:
    with tempfile.TemporaryDirectory() as folder:
        script, out = Path(folder) / "callers.py", Path(folder) / "callers.txt"
        script.write_text(GDB_SCRIPT)
        command = ["gdb", "-q", "-batch", "-p", str(pid), "-ex", f"set $limit={limit}", "-ex", f'set $out="{out}"']
        subprocess.run([*command, "-x", script], capture_output=True)
        counts = [line.split() for line in out.read_text().splitlines()]
    table = [line.split(maxsplit=2) for line in Path(f"/tmp/perf-{pid}.map").read_text().splitlines()]
    spans = sorted((int(a, 16), int(a, 16) + int(n, 16), readable(name)) for a, n, name in table)

    def owner(address):
        return next((name for start, end, name in spans if start <= address < end), "(not JIT code)")

    per = collections.Counter()
    for location, address, n in counts:
        per[(location, owner(int(address)))] += int(n)
    total = sum(per.values())
    lines = [f"{100 * n / total:5.1f}%  {location:<26} from {name}" for (location, name), n in per.most_common(25)]
    return f"{total} calls sampled\n" + "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trial", default="j7_1", help="a trial of data/paper_campaign")
    parser.add_argument("--seconds", type=float, default=20.0, help="how long perf samples")
    parser.add_argument("--refcounts", type=int, default=0, help="also sample this many reference counts' callers")
    args = parser.parse_args()
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="rc1-profile-")  # fresh: the code compiled, named
    context = multiprocessing.get_context("spawn")
    ready = context.Event()
    child = context.Process(target=replay_forever, args=(args.trial, ready), daemon=True)
    child.start()
    started = time.perf_counter()
    ready.wait()
    print(f"compiled in {time.perf_counter() - started:.0f} s; sampling process {child.pid}", file=sys.stderr)
    try:
        print(perf_profile(child.pid, args.seconds))
        if args.refcounts:
            print(callers(child.pid, args.refcounts))
    finally:
        child.kill()


if __name__ == "__main__":
    main()
