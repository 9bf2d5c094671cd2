"""Whether the study's second process pays: the whole `redundancy study` command, its cycle
section computed in a forked process (as the command does) against computed in place (as it is
beside other threads), alternately, in one run.

Run: python benchmarks/background.py [--repeat N]
Wall and CPU times (this process's children) on a machine that may be shared: the fork can only
gain where a core is free; printed, never asserted.
"""

import argparse
import resource
import subprocess
import sys
import tempfile
import time

# The command, with a thread started first where asked: `Background` then computes in place.
COMMAND = """
import sys, threading
if sys.argv.pop(1) == "in place":
    threading.Thread(target=threading.Event().wait, daemon=True).start()
from redundancy.cli import main
sys.exit(main(sys.argv[1:]))
"""


def run(how: str, out: str) -> tuple[float, float]:
    """Wall and CPU time (s) of one study command run ``how``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    arguments = [how, "study", "--quiet", "--out", out]
    subprocess.run([sys.executable, "-c", COMMAND, *arguments], check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return time.perf_counter() - start, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs of each (default 3)")
    repeat = parser.parse_args().repeat
    times: dict[str, list[tuple[float, float]]] = {"forked": [], "in place": []}
    with tempfile.TemporaryDirectory() as out:
        for _ in range(repeat):
            for how, found in times.items():
                found.append(run(how, out))
    for how, found in times.items():
        walls, cpus = zip(*found)
        print(f"{how:<9} wall {min(walls):6.1f} s (best of {repeat}), CPU {min(cpus):6.1f} s")
    ratio = min(w for w, _ in times["forked"]) / min(w for w, _ in times["in place"])
    print(f"forked / in place, wall: {ratio:.2f}")


if __name__ == "__main__":
    main()
