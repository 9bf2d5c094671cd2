"""How far the fast search and the paper's uniform sweep land from the least peak, on random
lines: this checkout after an earlier tree.

The lines are drawn over the slewing 3R arm's reach (the tests' arm, tests/data/slewing3r: three
links of 1.0, 0.8 and 0.5 m in the horizontal plane, every joint driven directly), the held
actuator turning with the line's number (x1, x2, x3, ...), at 0.2 m/s; with its slew's stroke one
turn ("slew_held.toml") or without end ("robot.toml"). A line some point of which is out of
reach (`check_path`), or whose start is, is left out. Per line, the reference is the least best
peak any search of either tree found there (each search's `best_peak`, on the grid); a search
is counted where it lands more than 1 % and 5 % above it, or finds no feasible start where some
search did. Motions: the mean number each search integrated per line.

Run: python benchmarks/search_accuracy.py [--before DIR] [--lines N] [--seeds S ...]
DIR is an earlier tree with its compiled core beside its sources, as `benchmarks/core.py` takes
one; each side runs in a process of its own. Printed, never asserted.
"""

import argparse
import json
import subprocess
from pathlib import Path

from study_cost import environment

ARM = Path(__file__).resolve().parents[1] / "tests" / "data" / "slewing3r"
FILES = ("slew_held.toml", "robot.toml")
SWEEP = 1000  # samples of the reference sweep
SPEED = 0.2  # m/s along every line


def measure(seeds: list[int], lines: int) -> list[dict]:
    """Each reachable line's best peaks, by the fast search and the sweep, with this package."""
    import warnings

    import numpy as np
    import pinocchio  # noqa: F401  (first: it loads the libraries the compiled core links)

    from redundancy import VELOCITY, Segment, improved_start, load_robot
    from redundancy.errors import InvalidInputError, UnreachableError
    from redundancy.planning.ik import check_path

    warnings.simplefilter("ignore")
    found = []
    for name in FILES:
        robot = load_robot(ARM / name)
        for seed in seeds:
            rng = np.random.default_rng(seed)
            for i in range(lines):
                start = rng.uniform(-1.6, 1.6, 2)
                direction = rng.normal(size=2)
                end = start + direction / np.linalg.norm(direction) * rng.uniform(0.3, 1.2)
                held = robot.actuators.names[i % robot.n]
                line = Segment(f"{seed}-{i}", start, end, SPEED)
                row: dict = {"file": name, "line": line.name, "held": held}
                try:
                    check_path(robot, line)
                    for method, samples in (("fast", 100), ("sweep", SWEEP)):
                        search = improved_start(robot, line, VELOCITY, held, samples, None, method)
                        row[method] = search.best_peak
                        row[f"{method} motions"] = search.simulations
                except (UnreachableError, InvalidInputError):
                    continue
                found.append(row)
    return found


def run(source: Path, seeds: list[int], lines: int) -> list[dict]:
    """`measure` in a process that imports the package from ``source``."""
    python, env = environment(source)
    command = [*python, str(Path(__file__).resolve()), "--measure", "--lines", str(lines)]
    command += ["--seeds", *map(str, seeds)]
    out = subprocess.run(command, cwd=source, env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="an earlier tree, its core built")
    parser.add_argument("--lines", type=int, default=60, help="lines per seed and file")
    parser.add_argument("--seeds", type=int, nargs="+", default=[13, 17])
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(args.seeds, args.lines)))
        return
    root = Path(__file__).resolve().parents[1]
    sides = {"after": run(root, args.seeds, args.lines)}
    if args.before:
        sides = {"before": run(args.before.resolve(), args.seeds, args.lines), **sides}
    keys = [(r["file"], r["line"]) for r in sides["after"]]
    for rows in sides.values():  # the lines both sides reach
        keys = [k for k in keys if k in {(r["file"], r["line"]) for r in rows}]
    by_side = {side: {(r["file"], r["line"]): r for r in rows} for side, rows in sides.items()}
    print(f"{len(keys)} lines reached, seeds {args.seeds}, {args.lines} per seed and file")
    print(f"{'side':<7} {'search':<6} {'> 1 %':>6} {'> 5 %':>6} {'none':>5} {'worst':>8} motions")
    for side, rows in by_side.items():
        for method in ("fast", "sweep"):
            above, missing, motions = [], 0, []
            for key in keys:
                peaks = [r[key][m] for r in by_side.values() for m in ("fast", "sweep")]
                peaks = [p for p in peaks if p is not None]
                if not peaks:
                    continue
                peak = rows[key][method]
                motions.append(rows[key][f"{method} motions"])
                if peak is None:
                    missing += 1
                else:
                    above.append(peak / min(peaks) - 1)
            over = [sum(a > limit for a in above) for limit in (0.01, 0.05)]
            mean = sum(motions) / max(len(motions), 1)
            print(
                f"{side:<7} {method:<6} {over[0]:>6} {over[1]:>6} {missing:>5} "
                f"{max(above, default=0):>+8.1%} {mean:.1f}"
            )


if __name__ == "__main__":
    main()
