"""What a design map costs, in one run: problems per second per core on the crane's paper-like
segments, solved in-process and on a local Dask cluster of 1 and 2 workers (in chunks of one
segment, and with 2 workers also in one chunk each); the scaling efficiency from 1 to 2
workers, beside the machine's own (two processes solving the family at once, without Dask:
what the cores give when both work); Dask's cost per chunk; and from these an estimate for 10⁶
problems on a 64-core cluster.

A problem is one segment with one objective (one row of the map). The family: every 2.5 m
horizontal segment (the length of the paper's 1-2) starting on a 6 × 5 grid over the crane's
workspace, with the velocity and the energy objective: 60 problems.

Run: python benchmarks/maps.py
"""

import multiprocessing
import tempfile
import time
from pathlib import Path

from redundancy.study.families import read_family
from redundancy.study.maps import design_map, local_client, solve_chunk

FAMILY = """
name = "paper-like segments"
chunk = {chunk}
[workspace]
length = 2.5
direction = [-1.0, 0.0]
[workspace.grid]
x = [2.5, 4.5, 6]
z = [-1.0, 2.0, 5]
"""


def family(folder: Path, chunk: int):
    path = folder / f"chunk{chunk}.toml"
    path.write_text(FAMILY.format(chunk=chunk))
    return read_family(path)


def timed(function) -> float:
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def solve_beside(family, ready, seconds) -> None:
    """In one of two processes: once warm and the other one too, solve ``family`` in one chunk
    and put the seconds it took."""
    solve_chunk(family, 0)
    ready.wait()
    seconds.put(timed(lambda: solve_chunk(family, 0)))


def both_at_once(family) -> float:
    """Seconds for two processes to solve ``family`` each, at once, without Dask."""
    context = multiprocessing.get_context("spawn")
    ready, seconds = context.Barrier(2), context.Queue()
    pair = [context.Process(target=solve_beside, args=(family, ready, seconds)) for _ in "ab"]
    for process in pair:
        process.start()
    wall = max(seconds.get(timeout=600) for _ in pair)
    for process in pair:
        process.join()
    return wall


def main() -> None:
    with tempfile.TemporaryDirectory() as folder:
        whole = family(Path(folder), 1000)
        singles = family(Path(folder), 1)
        halves = family(Path(folder), (len(whole) + 1) // 2)
        rows = 2 * len(whole)
        solve_chunk(whole, 0)  # warm: the robot is loaded once per process
        serial = min(timed(lambda: solve_chunk(whole, 0)) for _ in range(2))
        print(f"{rows} problems ({len(whole)} segments × 2 objectives)")
        print(f"in-process, one core: {serial:.2f} s, {rows / serial:.1f} problems/s")
        walls = {}
        for workers in (1, 2):
            with local_client(workers) as client:
                design_map(singles, client)  # warm the workers
                walls[workers] = min(timed(lambda: design_map(singles, client)) for _ in range(2))
            rate = rows / walls[workers] / workers
            print(
                f"Dask, {workers} worker(s), chunks of 1 segment: {walls[workers]:.2f} s, "
                f"{rate:.1f} problems/s per core"
            )
            if workers == 2:
                with local_client(workers) as client:
                    design_map(halves, client)
                    wall = min(timed(lambda: design_map(halves, client)) for _ in range(2))
                print(
                    f"Dask, 2 workers, one chunk each ({halves.chunks} chunks): {wall:.2f} s, "
                    f"{rows / wall / 2:.1f} problems/s per core"
                )
        both = both_at_once(whole)
        efficiency = walls[1] / (2 * walls[2])
        print(
            f"scaling efficiency 1 → 2 workers: {100 * efficiency:.0f} % (the machine's own, "
            f"two processes solving at once without Dask: {100 * serial / both:.0f} %)"
        )
        per_chunk = (walls[1] - serial) / singles.chunks
        print(f"Dask's cost per chunk (1 worker, against in-process): {1e3 * per_chunk:.1f} ms")
        problems, cores, chunk = 1e6, 64, 64
        per_problem = serial / rows
        estimate = problems * per_problem / (cores * efficiency)
        estimate += problems / 2 / chunk * max(per_chunk, 0.0) / cores
        print(
            f"estimate, 10⁶ problems on {cores} cores in chunks of {chunk} segments: "
            f"{estimate / 60:.0f} min"
        )


if __name__ == "__main__":
    main()
