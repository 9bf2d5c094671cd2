"""The main job's cost against an earlier commit, in one run: `redundancy study` with its
defaults, CPU time (user + sys of the command and every process it waited for) and wall time,
this checkout against ``--against REV``, the two run in turn so that a drift of the machine's
speed touches both alike.

Run: python benchmarks/study_cost.py --against f72f75b [--runs 5]
The earlier commit is taken with `git archive` into a temporary folder and imported from there,
with this environment's packages; where it has a compiled core, that core is built from its own
sources (a minute or two), or copied from this environment's where the sources are the same.
Medians and the ratio this / earlier are printed, never asserted.
"""

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def environment(source: Path) -> tuple[list[str], dict[str, str]]:
    """The interpreter's command and environment that import the package from ``source``. This
    checkout's is installed (editable: its import hook comes before PYTHONPATH, and its
    compiled core is built there); an earlier tree runs without the site hooks (-S), from its
    folder ahead of the folders this environment's site hooks add (Pinocchio's among them)."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    if source == ROOT:
        return [sys.executable], env
    others = [p for p in filter(None, sys.path) if not ROOT.is_relative_to(p)]  # not this tree
    env["PYTHONPATH"] = os.pathsep.join([str(source), *others])
    return [sys.executable, "-S"], env


def compiled_core(earlier: Path, scratch: Path) -> None:
    """Put the earlier tree's compiled core, `redundancy._core`, beside its package: this
    environment's build where its C++ sources and CMake file are this checkout's, else a build
    of its own sources, as pip builds the package."""
    sources = ["CMakeLists.txt", *(f"src/{p.name}" for p in sorted((earlier / "src").glob("*")))]
    if not (earlier / "CMakeLists.txt").exists():
        return  # a tree from before the compiled core
    import redundancy._core as core

    if all(
        (ROOT / name).exists() and (ROOT / name).read_bytes() == (earlier / name).read_bytes()
        for name in sources
    ):
        shutil.copy(core.__file__, earlier / "redundancy")
        return
    # built as pip builds it, then its extension taken out of the wheel; its run path finds
    # Boost.Serialization beside the package, as installed, through a link to this environment's
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(scratch), str(earlier)],
        check=True,
        capture_output=True,
    )
    with zipfile.ZipFile(next(scratch.glob("redundancy-*.whl"))) as wheel:
        (name,) = (n for n in wheel.namelist() if n.startswith("redundancy/_core"))
        (earlier / name).write_bytes(wheel.read(name))
    (earlier / "cmeel.prefix").symlink_to(Path(core.__file__).parents[1] / "cmeel.prefix")


def cost(source: Path, out: Path) -> tuple[float, float]:
    """(CPU seconds, wall seconds) of one `redundancy study --quiet` importing ``source``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    python, env = environment(source)
    command = [*python, "-m", "redundancy", "study", "--quiet", "--out", str(out)]
    wall = -time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, cwd=source, env=env)
    wall += time.perf_counter()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", required=True, help="the earlier commit, e.g. f72f75b")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        earlier = Path(scratch) / "earlier"
        earlier.mkdir()
        archive = subprocess.run(
            ["git", "archive", args.against], cwd=ROOT, check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(earlier)], input=archive, check=True)
        if (earlier / "robots").is_dir():  # a tree from before the robots moved into the package
            (earlier / "redundancy" / "robots").symlink_to(earlier / "robots")
        compiled_core(earlier, Path(scratch))
        for source in (ROOT, earlier):  # each side imports its own package, or nothing is measured
            python, env = environment(source)
            where = subprocess.run(
                [*python, "-c", "import redundancy; print(redundancy.__file__)"],
                cwd=source,
                env=env,
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            if not Path(where.strip()).is_relative_to(source):
                raise SystemExit(f"{source} imports the package from {where.strip()}")
        figures: dict[str, list[tuple[float, float]]] = {"this": [], "earlier": []}
        for run in range(args.runs + 1):  # the first pair warms the caches and is not counted
            for name, source in (("this", ROOT), ("earlier", earlier)):
                measured = cost(source, Path(scratch) / f"{name}-{run}")
                if run:
                    figures[name].append(measured)
    print(f"redundancy study, defaults; {args.runs} runs each, medians")
    medians = {
        name: [statistics.median(m[i] for m in runs) for i in (0, 1)]
        for name, runs in figures.items()
    }
    for i, what in enumerate(("CPU (user + sys)", "wall")):
        this, earlier_value = medians["this"][i], medians["earlier"][i]
        print(
            f"{what:<17} this {this:6.2f} s   {args.against} {earlier_value:6.2f} s   "
            f"ratio {this / earlier_value:.2f}"
        )


if __name__ == "__main__":
    main()
