"""Design maps: a family of planning problems (`redundancy.study.families`) solved on Dask, one
row per problem and objective.

Each problem is solved on its own, the same way wherever it runs: the improved start by the
fast search for every objective at once (`improved_starts`: one reachable scan serves them
all), and the default start (`default_start`) evaluated by the same integration, so that

    gain % = 100 (peak at the default start − best peak) / peak at the default start.

Rows therefore do not depend on how problems are grouped into chunks, nor on which worker
solves them: a map with 1 or N workers gives identical rows.

Problems are grouped in chunks of the family's ``chunk`` problems; each chunk is one Dask task.
On a local `distributed.LocalCluster` of worker processes by default, or on the caller's
`distributed.Client`. With a ``store`` folder, each finished chunk is written there at once as
its own Parquet file (written to a temporary name, then renamed), beside ``family.json`` naming
the family's fingerprint and the manifest ``chunks.jsonl``, where a line per chunk gives its
problem range and the SHA-256 of its file, appended before the file is put in place. A map run
again with the same family keeps the chunks the manifest vouches for and solves only the others:
a chunk file that is damaged (truncated, emptied, overwritten), another chunk's, or not in the
manifest is solved again, with one line saying so. A store that holds another family's chunks is
emptied first. A scheduler lost mid-run ends the map in one line; its finished chunks stay.

Columns: ``problem``, ``segment``, ``start_<axis>``, ``end_<axis>``, the design parameters the
grid varies (``payload`` kg, ``speed`` m/s, ``attachment`` m, ``bore`` m), ``objective``,
``unit``, ``reachable``, ``feasible``, per held actuator ``low_<a>``/``high_<a>`` (the feasible
range) and ``best_<a>``, ``peak``, ``default_<a>``, ``default_peak``, ``default_feasible``,
``gain_pct``; with the family's ``bound``, ``bound_peak``, ``motion_peak`` (the best start's
motion's peak on the 10 ms grid, where ``peak`` is the search's estimate at its samples),
``gap_pct`` against it and ``bound_reason``, why a problem has no bound; with ``energy``, the
best motion's ``ls_energy_kj``, ``cp_energy_kj`` and ``peak_flow_lpm``; and ``reason``, why a
problem has no feasible start.
"""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import hashlib
import io
import json
import logging
import os
import shutil
import urllib.parse
import uuid
import warnings
from collections.abc import Iterator
from concurrent.futures import CancelledError
from pathlib import Path

import numpy as np

from redundancy.errors import (
    InvalidInputError,
    RedundancyError,
    SchedulerLostError,
    SingularConfigurationError,
    UnreachableError,
)
from redundancy.model.hydraulics import LITRES_PER_MINUTE
from redundancy.planning.bound import global_optimum
from redundancy.planning.starts import Starts, default_start, evaluate_starts, improved_starts
from redundancy.resolution.limits import Limits
from redundancy.resolution.objectives import OBJECTIVES
from redundancy.study.families import Design, MapFamily, read_family
from redundancy.study.output import write_atomically
from redundancy.study.peers import pump_energies
from redundancy.study.signals import check, deferred, unheard

CONNECT_TIMEOUT = 10.0  # s a scheduler has to answer
FAMILY_FILE = "family.json"
MANIFEST = "chunks.jsonl"  # a line per finished chunk: {"chunk", "problems", "sha256"}
UNITS = {"payload": "kg", "speed": "m/s", "attachment": "m", "bore": "m"}  # each design
# parameter's, as its column holds it


def solve_chunk(family: MapFamily, chunk: int):
    """The rows of chunk number ``chunk`` of ``family`` (problem-major, objectives in order),
    as a DataFrame with the map's columns: built where the chunk is solved, on its worker."""
    rows = []
    for index, segment, design in family.problems(chunk):
        rows.extend(solve_problem(family, index, segment, design))
    return _frame(rows, columns(family, family.robot_for(Design()).task_axes))


def solve_problem(family: MapFamily, index: int, segment, design: Design) -> list[dict]:
    """One row per objective for problem ``index``: ``segment`` on ``design``."""
    robot = family.robot_for(design)
    segment = family.segment_for(segment, design)
    objectives = [OBJECTIVES[name] for name in family.objectives]
    problem: dict = {"problem": index, "segment": segment.name}
    for axis, start, end in zip(robot.task_axes, segment.start, segment.end):
        problem[f"start_{axis}"], problem[f"end_{axis}"] = float(start), float(end)
    for key, _ in family.grid:
        problem[key] = getattr(design, key)
    empty = {"reachable": False, "feasible": False, "peak": None, "default_peak": None}
    try:
        searches = improved_starts(robot, segment, objectives, family.held, circuit=family.circuit)
        values, q = default_start(robot, segment, family.held)
    except (UnreachableError, SingularConfigurationError) as error:  # a finding, not a fault
        return [
            {**problem, "objective": o.name, "unit": o.value_unit(robot.actuators), **empty}
            | {"reason": str(error)}
            for o in objectives
        ]
    margin = Limits.joints(robot).margin(q[None])
    start = Starts(values[None], q[None], margin, np.zeros(1))
    rows = []
    for objective, search in zip(objectives, searches):
        row = {
            **problem,
            "objective": objective.name,
            "unit": objective.value_unit(robot.actuators),
        }
        fallback = evaluate_starts(
            robot, segment, objective, family.held, start, circuit=family.circuit
        ).samples[0]
        best, box = search.best, search.feasible_box
        row.update(reachable=True, feasible=best is not None)
        for a, name in enumerate(family.held):
            row[f"low_{name}"] = None if box is None else float(box[a, 0])
            row[f"high_{name}"] = None if box is None else float(box[a, 1])
            row[f"best_{name}"] = None if best is None else best.values[a]
            row[f"default_{name}"] = float(values[a])
        row.update(
            peak=None if best is None else best.peak,
            default_peak=fallback.peak,
            default_feasible=fallback.feasible,
            gain_pct=_gain(best.peak if best else None, fallback.peak),
            reason=None if best else _why_none(search),
        )
        if family.bound:
            row.update(_bound(family, robot, segment, objective, search))
        if family.energy:
            row.update(_energy(search))
        rows.append(row)
    return rows


def _gain(best: float | None, default: float | None) -> float | None:
    if best is None or default is None or not default > 0:
        return None
    return 100 * (default - best) / default


def _why_none(search) -> str:
    closest = search.closest_violation
    reasons = {s.reason for s in search.samples if s.reason}
    return str(closest) if closest is not None else "; ".join(sorted(reasons)[:2])


def _bound(family, robot, segment, objective, search) -> dict:
    """The min-max bound over the held actuators' histories, the best start's motion's peak
    and its gap to the bound; ``bound_reason`` says why there is no bound: no feasible start,
    an integral objective, the solver's failure, or a bound withheld against the peak
    (`GlobalOptimum.withheld`), as the study says it."""
    row: dict = {"bound_peak": None, "motion_peak": None, "gap_pct": None, "bound_reason": None}
    if search.best is None:
        return row | {"bound_reason": "no feasible start"}
    row["motion_peak"] = peak = search.best_peak
    try:
        optimum = global_optimum(robot, segment, objective, family.held, search=search)
    except RedundancyError as error:
        return row | {"bound_reason": str(error)}
    withheld = optimum.withheld(peak)
    if withheld is not None:
        return row | {"bound_reason": withheld}
    gap = 100 * (peak - optimum.bound) / optimum.bound
    return row | {"bound_peak": optimum.bound, "gap_pct": gap}


def _energy(search) -> dict:
    """Pump energy under load sensing and constant pressure (kJ) and the peak pump flow
    (L/min) of the best start's motion."""
    if search.best is None:
        return {"ls_energy_kj": None, "cp_energy_kj": None, "peak_flow_lpm": None}
    motion = search.best_motion
    peak_flow = float(motion.flows.pump_flow[0].max() / LITRES_PER_MINUTE)
    return {**pump_energies(motion), "peak_flow_lpm": peak_flow}


class ChunkStore:
    """The finished chunks of ``family`` in ``folder`` (see the module docstring): those the
    manifest vouches for are `kept`, as DataFrames of the map's ``typed`` columns; `add` puts a
    new one in place, its manifest line first."""

    def __init__(self, folder: Path, family: MapFamily, typed: dict[str, str]):
        self.folder, self.family = folder, family
        self.kept = self._verified(typed)

    def path(self, chunk: int) -> Path:
        return self.folder / f"chunk-{chunk:06d}.parquet"

    def problems(self, chunk: int) -> list[int]:
        """The first and last problem of chunk number ``chunk``."""
        first = chunk * self.family.chunk
        return [first, min(first + self.family.chunk, len(self.family)) - 1]

    def add(self, chunk: int, frame) -> None:
        """Chunk ``chunk``'s rows, as a Parquet file whose manifest line is written first: a
        run cut short between the two leaves a line without its file, which is solved again."""
        data = frame.to_parquet()
        record = {
            "chunk": chunk,
            "problems": self.problems(chunk),
            "sha256": hashlib.sha256(data).hexdigest(),
        }
        with (self.folder / MANIFEST).open("a") as manifest:
            manifest.write(json.dumps(record) + "\n")
        write_atomically(self.path(chunk), lambda p: p.write_bytes(data))

    def _verified(self, typed: dict[str, str]) -> dict:
        """The chunks whose files match their manifest lines, read; every other chunk file is
        removed, with one line saying why."""
        import pandas as pd

        vouched = {}
        manifest = self.folder / MANIFEST
        lines = manifest.read_text().splitlines() if manifest.is_file() else []
        for line in lines:
            with contextlib.suppress(ValueError, TypeError, KeyError):  # a line cut short
                record = json.loads(line)
                vouched[int(record["chunk"])] = record
        kept = {}
        for path in sorted(self.folder.glob("chunk-*.parquet")):
            number = path.stem[len("chunk-") :]
            chunk = int(number) if number.isdigit() else -1
            record = vouched.get(chunk)
            data = path.read_bytes()
            if record is None or not 0 <= chunk < self.family.chunks:
                why = "not in the store's manifest"
            elif hashlib.sha256(data).hexdigest() != record["sha256"]:
                why = "damaged: its checksum differs from the manifest's"
            elif record["problems"] != self.problems(chunk):
                why = f"holds problems {record['problems']}, not {self.problems(chunk)}"
            else:
                frame = pd.read_parquet(io.BytesIO(data)).astype(typed)
                problems = [int(frame["problem"].min()), int(frame["problem"].max())]
                if problems == self.problems(chunk):
                    kept[chunk] = frame
                    continue
                why = f"holds problems {problems}, not {self.problems(chunk)}"
            warnings.warn(f"map store {self.folder}: {path.name} {why}; solved again", stacklevel=2)
            path.unlink()
        return kept


@contextlib.contextmanager
def _store(folder: Path, family: MapFamily, typed: dict[str, str]) -> Iterator[ChunkStore]:
    """The store of finished chunks in ``folder``, locked for this run (emptied first if it
    held another family's).

    A map that fails for its input (a `RedundancyError`: run again, it would fail again)
    removes the store; one interrupted, or cut short by a lost worker, scheduler or connection,
    keeps its finished chunks for the rerun."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(folder, os.O_RDONLY)
    except OSError as error:
        raise InvalidInputError(
            f"cannot write the map's chunks to {folder} ({error.strerror})"
        ) from None
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InvalidInputError(
                f"another map is writing to {folder}; wait for it, or give another --out"
            ) from None
        marker = folder / FAMILY_FILE
        try:
            same = json.loads(marker.read_text()).get("fingerprint") == family.fingerprint
        except (OSError, ValueError, AttributeError):  # none yet, or not the toolkit's
            same = False
        if not same:
            for entry in folder.iterdir():
                entry.unlink() if entry.is_file() else shutil.rmtree(entry)
            record = {
                "fingerprint": family.fingerprint,
                "name": family.name,
                "chunks": family.chunks,
            }
            write_atomically(marker, lambda p: p.write_text(json.dumps(record)))
        try:
            yield ChunkStore(folder, family, typed)
        except SchedulerLostError:
            raise
        except RedundancyError:
            shutil.rmtree(folder)
            raise
    finally:
        os.close(descriptor)


def columns(family: MapFamily, task_axes: str) -> dict[str, str]:
    """The map's columns and their types, in order (see the module docstring)."""
    typed = {"problem": "int64", "segment": "string"}
    for axis in task_axes:
        typed |= {f"start_{axis}": "float64", f"end_{axis}": "float64"}
    typed |= {key: "float64" for key, _ in family.grid}
    typed |= {"objective": "string", "unit": "string", "reachable": "bool", "feasible": "bool"}
    for name in family.held:
        typed |= {f"low_{name}": "float64", f"high_{name}": "float64", f"best_{name}": "float64"}
    typed["peak"] = "float64"
    typed |= {f"default_{name}": "float64" for name in family.held}
    typed |= {"default_peak": "float64", "default_feasible": "boolean", "gain_pct": "float64"}
    if family.bound:
        typed |= {"bound_peak": "float64", "motion_peak": "float64", "gap_pct": "float64"}
        typed["bound_reason"] = "string"
    if family.energy:
        typed |= {"ls_energy_kj": "float64", "cp_energy_kj": "float64", "peak_flow_lpm": "float64"}
    typed["reason"] = "string"
    return typed


def _frame(rows: list[dict], typed: dict[str, str]):
    """``rows`` as a DataFrame with the map's columns and types (None → missing)."""
    import pandas as pd

    # typed column by column, as arrays: a frame of objects converted after costs 2.5 times as
    # much, and a Series per column twice as much (a chunk of one segment: 1.0 against 0.5 ms)
    arrays = {
        name: pd.array([row.get(name) for row in rows], dtype=kind) for name, kind in typed.items()
    }
    return pd.DataFrame(arrays, copy=False)


def scheduler_address(text: str) -> str:
    """``text`` as a scheduler's address, tcp://HOST:PORT; one line naming that form
    otherwise."""
    try:
        parts = urllib.parse.urlsplit(text)
        valid = (
            parts.scheme == "tcp"
            and bool(parts.hostname)
            and parts.username is None
            and (parts.port or 0) > 0
            and not (parts.path or parts.query or parts.fragment)
            and not any(c.isspace() for c in text)
        )
    except ValueError:  # a port out of range, a malformed IPv6 address
        valid = False
    if not valid:
        raise InvalidInputError(
            f"--scheduler {text!r} is not a scheduler's address; give tcp://HOST:PORT, as "
            "`dask scheduler` prints it (e.g. tcp://10.0.0.5:8786)"
        )
    return f"tcp://{parts.netloc}"


async def _identity(address: str, timeout: float):
    """What the server at ``address`` says it is, asked in Dask's protocol (a scheduler
    answers a dict with ``"type": "Scheduler"``)."""
    from distributed.comm import connect as open_comm

    comm = await open_comm(address, timeout=timeout)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def connect(scheduler: str, timeout: float = CONNECT_TIMEOUT):
    """A `distributed.Client` on the scheduler at ``scheduler`` (tcp://HOST:PORT, e.g.
    tcp://10.0.0.5:8786), or one line if the address is malformed, if no scheduler answers
    there within ``timeout`` s or if what answers is not a Dask scheduler.

    The server is asked what it is before the Client is made: distributed bounds the TCP
    connection by the timeout but not its handshake, so a server that accepts and stays
    silent would hold the Client forever, and one that answers in another protocol would
    leave a half-made Client that complains when it is collected."""
    from distributed import Client

    scheduler = scheduler_address(scheduler)
    silent = InvalidInputError(
        f"--scheduler {scheduler}: no Dask scheduler answered within {timeout:g} s; start one "
        "with `dask scheduler` and give its address, e.g. tcp://HOST:8786"
    )
    try:
        identity = asyncio.run(asyncio.wait_for(_identity(scheduler, timeout), timeout))
    except OSError:  # refused, unreachable, or silent until the timeout (TimeoutError)
        raise silent from None
    except Exception:  # another protocol: its bytes, read as Dask's frames, fail anyhow
        identity = None
    if not (isinstance(identity, dict) and identity.get("type") == "Scheduler"):
        raise InvalidInputError(
            f"--scheduler {scheduler} does not answer as a Dask scheduler (something else "
            "listens there); start one with `dask scheduler` and give its address, e.g. "
            "tcp://HOST:8786"
        )
    # a scheduler lost later is told in one line (`SchedulerLostError`), not in the client's log of
    # its attempts to reconnect, with tracebacks
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    try:
        return Client(scheduler, timeout=timeout, set_as_default=False)
    except OSError:  # gone since it answered
        raise silent from None


def design_map(
    family: MapFamily | Path | str,
    client=None,
    workers: int | None = None,
    store: Path | str | None = None,
    progress: bool = False,
):
    """Solve every problem of ``family`` (a `MapFamily` or a map file) and return the rows as a
    pandas DataFrame, in problem order.

    Runs on ``client`` if given, else on a local cluster of ``workers`` worker processes (one
    thread each; default: the core count, at most what the free memory holds: `local_workers`).
    With ``store``, finished chunks are kept there and a rerun solves only the missing ones (see
    the module docstring)."""
    import pandas as pd
    from tqdm import tqdm

    if not isinstance(family, MapFamily):
        family = read_family(family)
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or not workers >= 1
    ):
        raise InvalidInputError(f"workers must be a whole number ≥ 1; got {workers!r}")
    local = None if client is not None else local_workers(workers)  # a local cluster's size
    typed = columns(family, family.robot_for(Design()).task_axes)
    with contextlib.ExitStack() as stack:
        chunks = None if store is None else stack.enter_context(_store(Path(store), family, typed))
        frames = {} if chunks is None else dict(chunks.kept)
        pending = [c for c in range(family.chunks) if c not in frames]
        bar = stack.enter_context(
            tqdm(
                total=len(family),
                initial=sum(frame["problem"].nunique() for frame in frames.values()),
                unit="problem",
                desc=family.name,
                disable=not progress,
                mininterval=0.5,
            )
        )
        if pending:
            if local is not None:
                client = stack.enter_context(local_client(local))
            from distributed import as_completed

            run = uuid.uuid4().hex[:8]  # keys of this run alone: a shared client may hold others
            # the family goes to each worker once, not with every chunk (a workspace family of
            # 100,000 starts pickles to 23 MB); a local cluster closed while its scheduler copies
            # it between workers logs that scheduler's failure: a signal waits for the copy
            with deferred() if local is not None else contextlib.nullcontext():
                shared = client.scatter(family, broadcast=True, hash=False)
            futures = {
                client.submit(solve_chunk, shared, c, key=f"map-{run}-chunk-{c}"): c
                for c in pending
            }
            try:
                for future in as_completed(futures, loop=client.loop):
                    chunk = futures[future]
                    frame = future.result()
                    if chunks is not None:
                        chunks.add(chunk, frame)
                    frames[chunk] = frame
                    bar.update(frame["problem"].nunique())
                    check()  # a Ctrl-C a library swallowed stops the map here, its chunks kept
            except (OSError, CancelledError) as error:  # the scheduler or its connection lost
                raise SchedulerLostError(
                    f"map {family.name!r}: the Dask scheduler was lost after {len(frames)} of "
                    f"{family.chunks} chunks ({type(error).__name__}); "
                    + (
                        "its finished chunks are kept: run the same command again to solve the rest"
                        if chunks is not None
                        else "nothing was kept"
                    )
                ) from None
        table = pd.concat([frames[c] for c in sorted(frames)], ignore_index=True)
        if not table["reachable"].any():  # final: the store goes with it
            raise InvalidInputError(
                f"map {family.name!r}: none of its {len(family)} problems is reachable, e.g. "
                f"{table['reason'].iloc[0]}"
            )
    return table


WORKER_MEMORY = 300e6
"""Bytes a local worker process holds once it has loaded the toolkit and solved a chunk (about
235 MB measured on the crane, with room for larger robots' chunks)."""


def local_workers(workers: int | None, named: str | None = None) -> int:
    """How many worker processes a local cluster starts: ``workers``, or by default one per
    core this process may run on; at most as many as the memory now available holds at
    `WORKER_MEMORY` each (a thousand workers asked for exhaust a workstation's memory before
    the first problem is solved). More asked for than fit is refused in one line, which begins
    with ``named`` (default "workers = N"); the default is cut to what fits."""
    import psutil

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    available = psutil.virtual_memory().available
    fit = max(1, int(available // WORKER_MEMORY))
    if workers is None:
        return min(cores or 1, fit)
    if workers > fit:
        raise InvalidInputError(
            f"{named or f'workers = {workers}'}: that many local worker processes need about "
            f"{workers * WORKER_MEMORY / 1e9:.1f} GB, and {available / 1e9:.1f} GB is free; "
            f"give at most {fit} (this machine has {cores} cores: one worker each is fastest)"
        )
    return workers


@contextlib.contextmanager
def local_client(workers: int):
    """A `distributed.Client` on a local cluster of ``workers`` worker processes
    (`local_workers`), one thread each, closed with the block.

    A Ctrl-C at a terminal reaches the whole process group: the map, not each of its workers
    with a traceback of its own, ends in one line and closes them. The workers never hear it
    (`unheard`), and the cluster is made whole before a signal is handled (`deferred`): one cut
    short half-way could be neither closed nor told to stop its workers, which would outlive
    the command with tracebacks of distributed's."""
    from multiprocessing import resource_tracker

    from distributed import Client, LocalCluster

    # Python's tracker of the processes' shared resources unblocks SIGINT in the thread that
    # starts it, with the first worker: started first, from here
    resource_tracker.ensure_running()
    with contextlib.ExitStack() as stack:
        with deferred(), unheard():
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address="127.0.0.1:0",  # a free port: two maps can run at once
                    silence_logs=logging.CRITICAL,  # a worker's restarts: not the user's business
                )
            )
            client = stack.enter_context(Client(cluster, set_as_default=False))
        yield client


def axes_of(table, family: MapFamily) -> list[str]:
    """The columns a map varies over, in the family's order: the workspace grid's start
    coordinates (those that take more than one value), or the segment, then the design grid's
    parameters."""
    starts = [c for c in table.columns if c.startswith("start_") and table[c].nunique() > 1]
    where = starts if family.segments[0].name.startswith("start ") else ["segment"]
    return where + [key for key, values in family.grid if len(values) > 1]


def design_words(parameters: list[str], design) -> str:
    """A design's values of the design ``parameters`` with their units (`UNITS`), as words:
    "payload = 250 kg, attachment = 0.35 m"; ``design`` is one value or a tuple of them."""
    values = design if isinstance(design, tuple) else (design,)
    return ", ".join(f"{key} = {value:g} {UNITS[key]}" for key, value in zip(parameters, values))


def summary(table, family: MapFamily) -> str:
    """One line: for a design grid, the design whose problems are all feasible with the least
    mean best peak (or integral) of the first objective over the segments (those some design
    keeps feasible: a workspace grid's start out of every design's reach says nothing of the
    designs), or every design that ties with it exactly (the velocity peak does not depend on
    the payload); otherwise,
    where the improved start gains most over the default start, among the problems where both
    keep the strokes (as the heatmap shows the gain)."""
    first = table[table["objective"] == family.objectives[0]]
    unit = first["unit"].iloc[0]
    peaked = OBJECTIVES[family.objectives[0]].reduction == "peak"
    measure = f"{family.objectives[0]}{' peak' if peaked else ''}"  # an integral: its value
    counts = f"{int(first['feasible'].sum())} of {len(first)} problems feasible"
    designs = [key for key, values in family.grid if len(values) > 1]
    if designs:
        # the segments some design keeps feasible: a workspace grid's start out of every
        # design's reach says nothing of the designs
        considered = first[first.groupby("segment")["feasible"].transform("any")]
        if considered.empty:
            return f"{family.name}: no design keeps every stroke on any segment ({counts})"
        grouped = considered.groupby(designs, sort=True)
        everywhere = grouped["feasible"].all()
        mean_peak = grouped["peak"].mean()[everywhere]
        segments, total = considered["segment"].nunique(), first["segment"].nunique()
        some = "" if segments == total else f" of the {segments} some design keeps"
        if mean_peak.empty:
            return f"{family.name}: no design keeps every stroke on every segment{some} ({counts})"
        least = mean_peak.min()
        tied = [design_words(designs, d) for d in mean_peak.index[mean_peak == least]]
        peak = (
            f"mean best {measure} {least:.4g} {unit} over {segments} "
            f"segment{'s' if segments > 1 else ''}"
            + ("" if segments == total else f" (of {total}: no design keeps the others)")
        )
        if len(tied) > 1:
            return (
                f"{family.name}: {len(tied)} designs tie for the least {peak}: "
                f"{'; '.join(tied)} ({counts})"
            )
        return f"{family.name}: best design {tied[0]}: {peak} ({counts})"
    both = (first["feasible"] & first["default_feasible"]).fillna(False).astype(bool)
    gains = first[both].dropna(subset=["gain_pct"])
    if gains.empty:
        return (
            f"{family.name}: no problem has a best and a default start that both keep the "
            f"strokes ({counts})"
        )
    row = gains.loc[gains["gain_pct"].idxmax()]
    starts = [c for c in table.columns if c.startswith("start_")]
    where = ", ".join(f"{c[6:]} = {row[c]:.3g}" for c in starts)
    return (
        f"{family.name}: the improved start gains most, {row['gain_pct']:.1f} % on the "
        f"{measure}, on segment {row['segment']} ({where} m); "
        f"median gain {gains['gain_pct'].median():.1f} % ({counts})"
    )
