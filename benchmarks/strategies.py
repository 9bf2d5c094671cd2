"""How good and how fast: every strategy on the crane's paper segments against the global bound,
and the cost of one control step against pink's.

For each paper segment (velocity objective, every stroke checked, payload 100 kg) it prints, and
writes as Markdown: each strategy's peak ẋᵀẋ, whether every stroke held, the gap to the global
bound and its planning time (what it computes before the motion can start); then the fast
search against a dense 1,000-sample sweep; the global optimum's convergence over its grids; the
energy objective on segment 1-2; the gradient-projection gain tuning; and the cost of one
control step, ours against pink's, measured in the same run. Every motion is measured alike: by
`simulate` (adaptive, sampled every 0.01 s; pink by its own control loop at 0.01 s, the global
optimum at its nodes).
Times are best-of-N wall times on a machine that may be shared; printed, never asserted.

Run: python benchmarks/strategies.py [--out benchmarks/results.md] [--quick]
(--quick skips the dense sweeps and the gain tuning: about a minute instead of several.)
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import os
import platform
import time
import timeit
from pathlib import Path

import numpy as np
from peers import (  # the script's folder: the peers
    TUNED_GAIN,
    gradient_projection_run,
    pseudoinverse_run,
    tune_gradient_projection,
)
from pink_peer import PinkResolver, pink_run

from redundancy import actuator_space, load_robot
from redundancy.planning.bound import global_optimum
from redundancy.planning.ik import inverse_kinematics
from redundancy.planning.starts import default_start, improved_start
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.laws import GradientProjection
from redundancy.resolution.objectives import ENERGY, VELOCITY
from redundancy.study.peers import StrategyRun

SAMPLES = 100  # the paper's sweep
DENSE = 1000  # the reference sweep for the fast search's targets
REPEATS = 7  # best of, for the planning times under a second


def best_time(function, repeat: int = REPEATS):
    """Least wall time of ``repeat`` calls (s), and the result."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def per_call(function, number: int, repeat: int = 9) -> float:
    """Best-of-``repeat`` seconds per call."""
    return min(timeit.repeat(function, number=number, repeat=repeat)) / number


def machine() -> str:
    """CPU model and cores, system, Python and library versions."""
    cpuinfo = Path("/proc/cpuinfo")
    lines = cpuinfo.read_text().splitlines() if cpuinfo.exists() else []
    models = [line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")]
    versions = ", ".join(
        f"{name} {importlib.metadata.version(name)}"
        for name in ("numpy", "scipy", "pin", "pin-pink", "daqp")
    )
    return (
        f"{models[0] if models else platform.processor() or 'unknown CPU'}, "
        f"{os.cpu_count()} cores, {platform.system()} {platform.machine()}; "
        f"Python {platform.python_version()}; {versions}"
    )


def table(header: list[str], rows: list[list]) -> list[str]:
    def row(cells):
        return "| " + " | ".join(str(c) for c in cells) + " |"

    return [row(header), row(["---"] * len(header)), *(row(r) for r in rows)]


def duration(seconds: float) -> str:
    return f"{seconds * 1e3:.1f} ms" if seconds < 1 else f"{seconds:.2f} s"


def gap(peak: float, bound: float) -> str:
    """(peak − bound) / bound in %, with differences below the solver's tolerance shown as 0."""
    percent = 100 * (peak - bound) / bound
    return f"{percent:+.2f}" if abs(percent) >= 0.005 else "0.00"


def limits(run: StrategyRun) -> str:
    motion = run.trajectory
    if motion.within_limits[0]:
        return "kept"
    return f"**no**: {max(motion.violations(0), key=lambda v: v.excess)}"


def strategies(robot, segment):
    """(run, planning seconds, what the planning covers) of every strategy, and the bound."""
    plan, bound = best_time(lambda: global_optimum(robot, segment), repeat=1)
    bound_run = StrategyRun(
        segment.name, "global optimum (the bound)", (bound.start,), bound.motion
    )
    fast_time, fast = best_time(lambda: improved_start(robot, segment, VELOCITY))
    sweep_time, sweep = best_time(
        lambda: improved_start(robot, segment, VELOCITY, "x3", SAMPLES, method="sweep"),
        repeat=1,
    )
    start_time, _ = best_time(lambda: default_start(robot, segment, "x3"))
    runs = [
        (bound_run, plan, f"{len(bound.grids)} grids, {bound.grids[-1].intervals} intervals"),
        (
            StrategyRun(segment.name, "improved, fast search", fast.best.values, fast.motion()),
            fast_time,
            f"{fast.simulations} motions in {fast.rounds} batch(es)",
        ),
        (
            StrategyRun(
                segment.name,
                f"improved, uniform sweep ({SAMPLES})",
                sweep.best.values,
                sweep.motion(sweep.best),
            ),
            sweep_time,
            f"{SAMPLES} motions",
        ),
    ]
    for peer in (pseudoinverse_run, gradient_projection_run, pink_run):
        runs.append((peer(robot, segment), start_time, "default start (IK)"))
    return runs, bound, fast, fast_time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("results.md"))
    parser.add_argument("--quick", action="store_true", help="skip the dense sweeps and tuning")
    arguments = parser.parse_args()
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    rows, targets, convergence = [], [], []
    for segment in cycle.segments:
        print(f"segment {segment.name}", flush=True)
        runs, bound, fast, fast_time = strategies(robot, segment)
        for run, seconds, covers in runs:
            peak = run.trajectory.peak_velocity_norm[0]
            rows.append(
                [
                    segment.name,
                    run.strategy,
                    f"{run.start[0]:.4f}",
                    f"{peak:.5f}",
                    limits(run),
                    gap(peak, bound.bound),
                    duration(seconds),
                    covers,
                ]
            )
        convergence.append(
            [
                segment.name,
                ", ".join(f"{g.intervals}: {g.peak:.6f}" for g in bound.grids),
                f"{100 * bound.change:.4f}",
                "yes" if bound.converged else "no",
                "; ".join(f"{g.iterations} iterations, {g.message}" for g in bound.grids),
            ]
        )
        if arguments.quick:
            continue
        print(f"  {DENSE}-sample sweep", flush=True)
        dense_time, dense = best_time(
            lambda s=segment: improved_start(robot, s, VELOCITY, "x3", DENSE, method="sweep"),
            repeat=1,
        )
        peak = fast.motion().peak_velocity_norm[0]
        targets.append(
            [
                segment.name,
                f"{fast_time * 1e3:.1f}",
                "[{:.4f}, {:.4f}]".format(*fast.feasible_range),
                "[{:.4f}, {:.4f}]".format(*dense.feasible_range),
                f"{fast.best.value:.4f} / {dense.best.value:.4f}",
                f"{peak:.6f} / {dense.best.peak:.6f}",
                f"{100 * (peak - dense.best.peak) / dense.best.peak:+.3f}",
                f"{dense_time:.1f}",
            ]
        )

    lines = [
        "# How good and how fast: strategies on the HIAB 031 paper segments",
        "",
        f"Measured {datetime.date.today().isoformat()} on {machine()}.",
        "",
        "Velocity objective (peak ẋᵀẋ), every stroke checked, payload 100 kg. Gap: (peak − bound)"
        " / bound. Planning: wall time before the motion can start (best of "
        f"{REPEATS} when under a second).",
        "",
        *table(
            [
                "segment",
                "strategy",
                "x3 at t = 0 (m)",
                "peak ẋᵀẋ (m²/s²)",
                "limits",
                "gap to bound (%)",
                "planning",
                "planning covers",
            ],
            rows,
        ),
        "",
        f"## Fast search against a {DENSE}-sample sweep",
        "",
    ]
    if targets:
        lines += table(
            [
                "segment",
                "fast search (ms)",
                "feasible x3init, fast (m)",
                f"feasible x3init, {DENSE} samples (m)",
                "best x3init, fast / dense (m)",
                "best peak, fast / dense (m²/s²)",
                "peak difference (%)",
                f"{DENSE}-sample sweep (s)",
            ],
            targets,
        )
        lines += ["", "Both peaks by `simulate` at 0.01 s from each best start."]
    else:
        lines.append("(skipped: --quick)")
    lines += ["", "## Global optimum: convergence over its grids", ""]
    lines += table(
        ["segment", "intervals: optimal peak", "last change (%)", "converged", "solver"],
        convergence,
    )

    print("energy objective, segment 1-2", flush=True)
    segment = cycle["1-2"]
    energy_bound = global_optimum(robot, segment, ENERGY)
    energy_peak = improved_start(robot, segment, ENERGY).motion().peak_kinetic[0]
    lines += ["", "## Energy objective (peak ẋᵀ M_H ẋ), segment 1-2", ""]
    lines += table(
        ["strategy", "peak ẋᵀ M_H ẋ (J)", "gap to bound (%)"],
        [
            ["global optimum", f"{energy_bound.bound:.3f}", "0"],
            ["improved, fast search", f"{energy_peak:.3f}", gap(energy_peak, energy_bound.bound)],
        ],
    )
    lines += ["", "No start keeps every stroke on 2-3 and 3-1 for this objective (x3 leaves its"]
    lines += ["stroke), as the study finds."]

    if not arguments.quick:
        print("gradient-projection gain tuning", flush=True)
        tuning = tune_gradient_projection(robot, cycle.segments)
        lines += ["", "## Gradient projection: gain tuning (default starts)", ""]
        lines += table(
            ["gain α (m²/s)", *(f"peak {s}" for s in tuning.segments), "every limit held"],
            [
                [
                    f"{gain:.4g}",
                    *(f"{p:.4f}" + ("" if w else " (limit passed)") for p, w in zip(peaks, held)),
                    "yes" if held.all() else "no",
                ]
                for gain, peaks, held in zip(tuning.gains, tuning.peaks, tuning.within)
            ],
        )
        lines += ["", f"Chosen: α = {tuning.chosen:.4g} m²/s (`peers.TUNED_GAIN` = {TUNED_GAIN})."]

    print("one control step", flush=True)
    segment = cycle["1-2"]
    q = inverse_kinematics(robot, segment.start, ["x3"], np.array([[1.0]])).q[0]
    y_dot = segment.velocity
    law = VELOCITY.resolver
    ours = per_call(lambda: law.step(robot, q, y_dot), 20000)
    generic = per_call(
        lambda: VELOCITY.resolver.resolve(actuator_space(robot, q), y_dot[None]), 3000
    )
    projection = GradientProjection(TUNED_GAIN)
    gradient = per_call(lambda: projection.resolve(actuator_space(robot, q), y_dot[None]), 3000)
    pink = PinkResolver(robot)
    target = actuator_space(robot, q).y[0] + y_dot * pink.time_step
    theirs = per_call(lambda: pink.control_step(q, target), 3000)
    lines += ["", "## One control step (one state on segment 1-2, best of 9)", ""]
    lines += table(
        ["step", "µs per step", "relative to ours"],
        [
            ["ours: `MinVelocityNorm().step`, min ẋᵀẋ (Eq. 24)", f"{ours * 1e6:.1f}", "1"],
            [
                "`actuator_space` + `MinVelocityNorm.resolve`",
                f"{generic * 1e6:.1f}",
                f"{generic / ours:.1f}",
            ],
            [
                f"`actuator_space` + `GradientProjection({TUNED_GAIN})`",
                f"{gradient * 1e6:.1f}",
                f"{gradient / ours:.1f}",
            ],
            [
                f"pink: `Configuration.update` + `solve_ik` ({pink.solver})",
                f"{theirs * 1e6:.1f}",
                f"{theirs / ours:.1f}",
            ],
        ],
    )
    lines += ["", f"pink's step costs {theirs / ours:.1f} times ours, measured in the same run."]
    text = "\n".join(lines) + "\n"
    print(text)
    arguments.out.write_text(text)
    print(f"written to {arguments.out}")


if __name__ == "__main__":
    main()
