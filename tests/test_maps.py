"""Design maps on Dask: a real scheduler and workers, resumable Parquet chunks, the paper's
findings reproduced, families read with one-line errors."""

import contextlib
import dataclasses
import functools
import itertools
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import types
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest
from commands import as_foreground, run_cli

from redundancy import LS_ENERGY, VELOCITY, WorkCycle, actuator_space, improved_start, load_robot
from redundancy.errors import InvalidInputError
from redundancy.model.loading import bundled_root
from redundancy.planning.tasks import Arc, Polyline, Segment
from redundancy.study import families
from redundancy.study.families import Design, MapFamily, read_family
from redundancy.study.maps import design_map, summary
from redundancy.study.study import run_study

BIN = Path(sys.executable).parent

WORKSPACE = """
name = "workspace"
objectives = ["velocity"]
chunk = {chunk}
[workspace]
length = 1.0
direction = [-1.0, 0.0]
[workspace.grid]
x = [1.5, 4.0, {nx}]
z = [-1.0, 2.0, 3]
"""


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address="127.0.0.1:0") as cluster,
        Client(cluster, set_as_default=False) as connected,
    ):
        yield connected


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def dask_cluster(folder: Path, workers: int):
    """A Dask scheduler and ``workers`` worker processes started as a user starts them, on a
    free port of this machine; yields the scheduler's address once the workers have joined, and
    the started processes (scheduler first)."""
    address = f"tcp://127.0.0.1:{free_port()}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    port = address.rsplit(":")[-1]
    scheduler = [BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port", port]
    started = [subprocess.Popen([*scheduler, "--no-dashboard"], **quiet)]
    worker = [BIN / "dask", "worker", address, "--nworkers", "1", "--nthreads", "1"]
    try:
        for _ in range(workers):
            started.append(
                subprocess.Popen(
                    [*worker, "--host", "127.0.0.1", "--no-dashboard"], cwd=folder, **quiet
                )
            )
        from distributed import Client

        with Client(address, timeout=30, set_as_default=False) as probe:
            probe.wait_for_workers(workers, timeout=600)
            assert len(probe.scheduler_info()["workers"]) == workers
        yield address, started
    finally:
        # the workers before the scheduler: a worker whose scheduler has gone first tries to
        # reach it again for seconds before it ends
        for process in started[::-1]:
            process.terminate()
        for process in started[::-1]:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def test_a_map_on_a_dask_cluster_by_address_equals_the_local_run(tmp_path, client):
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=3))
    with dask_cluster(tmp_path, 2) as (address, started):
        remote = run_cli("map", str(family), "--scheduler", address, "--out", str(tmp_path / "r"))
        assert remote.returncode == 0, remote.stderr
    assert all(p.poll() is not None for p in started)
    rows = pd.read_parquet(tmp_path / "r" / "map.parquet")
    pd.testing.assert_frame_equal(rows, design_map(family, client))
    assert len(rows) == 9 and rows["reachable"].any() and rows["feasible"].any()
    assert (tmp_path / "r" / "map_velocity.png").stat().st_size > 10_000
    assert not (tmp_path / ".r.chunks").exists()  # the chunks go once the map is in place


def test_the_map_figure_gives_the_held_actuators_values_their_unit(tmp_path, client):
    """The crane's telescope is a length: its best initial values are headed in m."""
    from redundancy.viz.map_figures import map_figure
    from redundancy.viz.plots import pyplot

    family = read_family(write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2)))
    assert family.held_unit == "m"
    figure = map_figure(design_map(family, client), family, "velocity")
    pyplot().close(figure)
    assert figure.axes[1].get_title() == f"best initial {family.held[0]} (m)"


def test_rows_do_not_depend_on_chunks_or_workers(tmp_path, client):
    one = design_map(write(tmp_path, "a.toml", WORKSPACE.format(chunk=1, nx=2)), workers=1)
    many = design_map(write(tmp_path, "b.toml", WORKSPACE.format(chunk=4, nx=2)), client)
    pd.testing.assert_frame_equal(one, many)


def test_an_interrupted_map_keeps_its_finished_chunks_and_solves_only_the_rest(tmp_path, client):
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=1, nx=8))
    store = tmp_path / ".out.chunks"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "redundancy.cli",
            "map",
            str(family),
            "--workers",
            "1",
            "--out",
            str(tmp_path / "out"),
            "--quiet",
        ],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 600
    while len(list(store.glob("chunk-*.parquet"))) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGTERM)
    _, stderr = process.communicate(timeout=600)
    assert process.returncode == 143, stderr
    assert stderr.strip().splitlines()[-1] == "redundancy: terminated"
    assert not (tmp_path / "out").exists()
    kept = {p.name: p.stat() for p in store.glob("chunk-*.parquet")}
    assert 3 <= len(kept) < 24, "the run must be cut short after its first chunks"

    out = str(tmp_path / "out")
    rerun = run_cli("map", str(family), "--workers", "1", "--out", out, terminal=True)
    assert rerun.returncode == 0, rerun.stderr
    assert not store.exists()
    # the kept chunks were read, not solved again: the progress bar starts at their count
    assert f"{len(kept)}/24" in rerun.stderr
    # the same rows as a map solved in one go
    pd.testing.assert_frame_equal(
        pd.read_parquet(tmp_path / "out" / "map.parquet"), design_map(family, client)
    )


def test_a_rerun_reads_each_kept_chunk_file_untouched(tmp_path, client):
    """Chunks already in the store are kept as they are (same inode and time stamp); a store
    of another family is emptied first."""
    family = read_family(write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2)))
    store = tmp_path / "store"
    first = design_map(family, client, store=store)
    files = sorted(store.glob("chunk-*.parquet"))
    assert len(files) == family.chunks == 3
    files[-1].unlink()  # as if the run had been cut short before its last chunk
    before = {f.name: (f.stat().st_ino, f.stat().st_mtime_ns) for f in files[:-1]}
    again = design_map(family, client, store=store)
    pd.testing.assert_frame_equal(first, again)
    assert {f.name: (f.stat().st_ino, f.stat().st_mtime_ns) for f in files[:-1]} == before
    other = read_family(write(tmp_path, "other.toml", WORKSPACE.format(chunk=3, nx=2)))
    design_map(other, client, store=store)
    assert sorted(p.name for p in store.glob("chunk-*.parquet")) == [
        "chunk-000000.parquet",
        "chunk-000001.parquet",
    ]


def test_a_map_of_the_paper_segments_reproduces_the_study(tmp_path, crane, client):
    cycle = WorkCycle.from_toml(crane.task_file, dimension=crane.m)
    study = run_study(crane, cycle, samples=2, bound=False, progress=False, cycles=0)
    rows = design_map(write(tmp_path, "paper.toml", "chunk = 2\n[task]\n"), client)
    assert len(rows) == 6
    for row in rows.itertuples():
        search = study.search(row.objective, row.segment)
        assert row.reachable
        if search.best is None:
            assert not row.feasible and np.isnan(row.peak) and row.reason
            continue
        assert row.feasible
        assert row.best_x3 == pytest.approx(search.best.value, rel=1e-12)
        assert row.peak == pytest.approx(search.best.peak, rel=1e-12)
        low, high = search.feasible_range
        assert (row.low_x3, row.high_x3) == pytest.approx((low, high), rel=1e-12)
        default = [r for r in study.runs if r.segment == row.segment and "default" in r.strategy]
        assert row.default_x3 == pytest.approx(default[0].start[0], rel=1e-12)
    velocity = rows[rows["objective"] == "velocity"].set_index("segment")
    gains = 100 * (velocity["default_peak"] - velocity["peak"]) / velocity["default_peak"]
    np.testing.assert_allclose(velocity["gain_pct"], gains, rtol=1e-12)
    assert (velocity["gain_pct"] > 0).all()  # the paper's finding: the improved start is better


def test_a_design_grid_moves_the_payload_the_speed_and_a_cylinder_attachment(tmp_path, client):
    robot = load_robot("hiab031")
    base = robot.actuators["x1"].base[1]
    moved = [float(base[0]), float(base[0]) + 0.05]
    family = read_family(
        write(
            tmp_path,
            "design.toml",
            f"""objectives = ["velocity"]
[task]
segments = ["1-2"]
[grid]
payload = [0, 400]
speed = {{from = 0.25, to = 0.5, count = 2}}
attachment = {{actuator = "x1", end = "base", axis = "x", values = {moved}}}
""",
        )
    )
    assert len(family) == 8
    q = np.array([1.7, 1.0, 0.5])
    shifted = family.robot_for(Design(payload=400.0, attachment=moved[1]))
    assert shifted.payload == 400.0
    # x1 = |p_rod − p_base| with the base point moved 5 cm along its link's x axis
    link, point = robot.actuators["x1"].base
    pin.framesForwardKinematics(robot.model, robot.data, q)
    base_world = robot.data.oMf[robot.model.getFrameId(link)] * np.array(
        [moved[1], point[1], point[2]]
    )
    rod_world = robot.data.oMf[robot.actuators["x1"].frames[1]].translation
    expected = np.linalg.norm(rod_world - base_world)
    assert actuator_space(shifted, q).x[0, 0] == pytest.approx(expected, rel=1e-12)
    assert actuator_space(robot, q).x[0, 0] != pytest.approx(expected, rel=1e-6)

    rows = design_map(family, client)
    assert rows[["payload", "speed", "attachment"]].drop_duplicates().shape[0] == 8
    # the energy objective is absent, so the payload leaves the velocity peak unchanged
    by_payload = rows.pivot_table(index=["speed", "attachment"], columns="payload", values="peak")
    np.testing.assert_allclose(by_payload[0.0], by_payload[400.0], rtol=1e-9)
    # ẋ scales with the task speed, so the peak of ẋᵀẋ with its square
    by_speed = rows.pivot_table(index=["payload", "attachment"], columns="speed", values="peak")
    np.testing.assert_allclose(by_speed[0.5] / by_speed[0.25], 4.0, rtol=2e-3)
    line = summary(rows, family)
    designs = rows.groupby(["payload", "speed", "attachment"])
    means = designs["peak"].mean()[designs["feasible"].all()]
    for payload, speed, attachment in means.index[means == means.min()]:
        said = f"payload = {payload:g} kg, speed = {speed:g} m/s, attachment = {attachment:g} m"
        assert said in line
    assert "2 designs tie" in line  # each payload: the velocity peak does not depend on it


def test_the_summary_s_gain_counts_only_problems_where_both_starts_keep_the_strokes():
    """A workspace map's line: the largest and the median gain among the problems whose best
    and default starts both keep the strokes, as the heatmap shows them; a gain against a
    default start that breaks a stroke (here the largest) is not one."""
    family = types.SimpleNamespace(name="workspace", objectives=("velocity",), grid=())
    table = pd.DataFrame(
        {
            "objective": "velocity",
            "unit": "m²/s²",
            "segment": ["1-2", "2-3", "3-1", "3-2"],
            "start_x": [3.5, 2.25, 1.0, 1.0],
            "feasible": [True, True, True, False],
            "default_feasible": pd.array([True, True, False, True], dtype="boolean"),
            "gain_pct": [62.5, 6.7, 70.1, np.nan],
        }
    )
    line = summary(table, family)
    assert "gains most, 62.5 % on the velocity peak, on segment 1-2" in line
    assert "median gain 34.6 %" in line and "(3 of 4 problems feasible)" in line
    table["default_feasible"] = False
    assert "no problem has a best and a default start that both keep" in summary(table, family)


def test_the_map_summary_gives_units_and_says_where_designs_tie():
    """Payload in kg and the attachment in m; designs whose mean best peak is the same (the
    velocity peak does not depend on the payload) are named together as a tie."""
    family = types.SimpleNamespace(
        name="lift base",
        objectives=("velocity",),
        grid=(("payload", (250.0, 500.0)), ("attachment", (0.3, 0.35))),
    )
    table = pd.DataFrame(
        {
            "objective": "velocity",
            "unit": "m²/s²",
            "segment": "pull-in",
            "payload": [250.0, 250.0, 500.0, 500.0],
            "attachment": [0.3, 0.35, 0.3, 0.35],
            "feasible": True,
            "peak": [0.02, 0.013, 0.02, 0.013],
        }
    )
    line = summary(table, family)
    assert "2 designs tie" in line
    assert "payload = 250 kg, attachment = 0.35 m; payload = 500 kg, attachment = 0.35 m" in line
    table.loc[3, "peak"] = np.nextafter(0.013, 1.0)
    line = summary(table, family)
    assert "best design payload = 250 kg, attachment = 0.35 m:" in line and "tie" not in line
    assert "mean best velocity peak 0.013 m²/s²" in line
    # a segment out of every design's reach (a workspace grid's far start) judges no design:
    # it said "no design keeps every stroke on every segment"
    far = table.assign(segment="far", feasible=False, peak=np.nan)
    line = summary(pd.concat([table, far], ignore_index=True), family)
    assert "best design payload = 250 kg, attachment = 0.35 m:" in line
    assert "over 1 segment (of 2: no design keeps the others)" in line
    # a pump energy is an integral: its least value, not a peak
    family.objectives = ("ls_energy",)
    table["objective"], table["unit"] = "ls_energy", "kJ"
    line = summary(table, family)
    assert "mean best ls_energy 0.013 kJ over 1 segment" in line and "peak" not in line


def test_with_circuit_limits_a_heavier_payload_needs_a_wider_lift_cylinder(tmp_path, client):
    """A bore grid moves the cylinder's area, so its load pressure p = F / A: with the
    circuit's limits counted, 1,500 kg passes the 210 bar relief in a narrow x1 and not in a
    wide one, while 100 kg stays under it in every bore."""
    family = read_family(
        write(
            tmp_path,
            "bore.toml",
            'objectives = ["velocity"]\ncircuit = true\n[task]\nsegments = ["1-2"]\n[grid]\n'
            'payload = [100, 1500]\nbore = {actuator = "x1", values = [0.05, 0.08, 0.12]}\n',
        )
    )
    wide = family.robot_for(Design(bore=0.12)).circuit()
    assert wide.cylinders[wide.names.index("x1")].bore == 0.12
    rows = design_map(family, client).set_index(["payload", "bore"])
    assert rows.loc[100.0, "feasible"].all()
    heavy = rows.loc[1500.0]
    assert list(heavy["feasible"]) == [False, False, True]
    for reason in heavy["reason"].iloc[:2]:
        assert reason.startswith("x1 load pressure") and "past its upper limit" in reason
    excess = [float(r.split("pressure ")[1].split(" bar")[0]) for r in heavy["reason"].iloc[:2]]
    assert excess[0] > excess[1]  # the narrower bore, the higher the pressure


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (WORKSPACE.format(chunk=1, nx=0), "count 0 must be a whole number ≥ 1"),
        (WORKSPACE.format(chunk=1, nx="true"), "count true must be a whole number ≥ 1"),
        (WORKSPACE.replace("[1.5, 4.0, {nx}]", '"all"').format(chunk=1), 'x = "all" must be'),
        ("[task]\n[grid]\npayload = []\n", "gives no values"),
        ("[task]\n[grid]\nspeed = {from = 0.1, to = 0.5, count = 0}\n", "count = 0"),
        ('objectives = ["fast"]\n[task]\n', "objective 'fast' unknown; objectives: velocity"),
        ("[task]\n[workspace]\n", "give the segments by one table"),
        ('[task]\n[grid]\nattachment = {actuator = "x9", values = [0.1]}\n', "no actuator 'x9'"),
        ("[task]\n[grid]\nwidth = [1]\n", "unknown parameters ['width']"),
        ("chunk = 0\n[task]\n", "chunk = 0 must be a whole number"),
        ("robot = 3\n[task]\n", "robot = 3 must be a string"),
        ("[task]\nsegments = []\n", "[task] segments = [] must not be empty: a list of names"),
        ('name = ""\n[task]\n', 'name = "" must not be empty: a string'),
    ],
)
def test_a_bad_family_gets_one_line(tmp_path, text, expected):
    with pytest.raises(InvalidInputError) as raised:
        read_family(write(tmp_path, "bad.toml", text))
    assert expected in str(raised.value)
    assert "\n" not in str(raised.value)


def test_the_documented_family_reads_as_the_page_says(tmp_path):
    """docs/maps.md's family, saved as workspace.toml, runs as it stands: it named a
    hydraulics file that no one has. 48 starts of the crane's workspace times two payloads and
    two lift-cylinder bases are 192 problems."""
    text = (Path(__file__).parents[1] / "docs" / "maps.md").read_text()
    start = text.index('```toml\nname = "workspace gain"') + len("```toml\n")
    family = read_family(write(tmp_path, "workspace.toml", text[start : text.index("```", start)]))
    assert family.name == "workspace gain" and len(family) == 192
    assert [key for key, _ in family.grid] == ["payload", "attachment"]


def test_a_family_is_counted_before_any_segment_is_built(tmp_path, monkeypatch):
    """3,000 × 1,000 starts are refused from the grid's counts, not after building 3,000,000
    segments (about a minute)."""

    def built(*args):
        raise AssertionError("a segment was built")

    monkeypatch.setattr(families, "Segment", built)
    text = WORKSPACE.format(chunk=8, nx=3000).replace("[-1.0, 2.0, 3]", "[-1.0, 2.0, 1000]")
    with pytest.raises(InvalidInputError, match="the family has 3,000,000 problems"):
        read_family(write(tmp_path, "big.toml", text))


def test_a_robot_s_note_is_said_once_not_again_by_each_worker(tmp_path):
    """The slewing crane with its slew's declaration left out: loading it says once that the
    slew is driven directly. The workers load it (and its payload variants) again, and each
    printed Python's raw warning, its source line included."""
    urdf = (bundled_root() / "hiab031_slewing" / "hiab031_slewing.urdf").read_text()
    urdf = re.sub(r'<transmission name="slew">.*?</transmission>', "", urdf, flags=re.S)
    (tmp_path / "crane.urdf").write_text(urdf)
    (tmp_path / "robot.toml").write_text(
        'urdf = "crane.urdf"\ntool_frame = "tool"\ntask_axes = "xyz"\npayload = 100.0\n'
    )
    family = write(
        tmp_path,
        "m.toml",
        'robot = "robot.toml"\nobjectives = ["velocity"]\nheld = ["x3"]\nchunk = 1\n'
        '[task]\nfile = "t.toml"\n[grid]\npayload = [0, 200]\n',
    )
    (tmp_path / "t.toml").write_text(
        'segments = ["a-b"]\n[points]\na = [2.5, 0.0, 0.5]\nb = [2.5, 0.5, 0.5]\n'
    )
    result = run_cli("map", str(family), "--workers", "2", "--out", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    assert f"start here: {tmp_path / 'out' / 'index.html'}" in result.stdout  # as study's
    notes = result.stderr.strip().splitlines()
    assert len(notes) == 1 and notes[0].startswith("redundancy: note: joints without"), notes


def test_bad_map_runs_get_one_line_and_exit_2(tmp_path):
    nowhere = write(
        tmp_path, "far.toml", WORKSPACE.format(chunk=2, nx=2).replace("[1.5, 4.0", "[40.0, 50.0")
    )
    result = run_cli("map", str(nowhere), "--workers", "1", "--out", str(tmp_path / "far"))
    assert result.returncode == 2
    assert (
        result.stderr.strip()
        .splitlines()[-1]
        .startswith("redundancy: error: map 'workspace': none of its 6 problems is reachable")
    )
    assert not (tmp_path / "far").exists()

    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2))
    silent = f"tcp://127.0.0.1:{free_port()}"
    # The timeouts guard a hang only: a loaded machine may take long to start the command
    result = run_cli(
        "map", str(family), "--scheduler", silent, "--timeout", "2", cwd=tmp_path, timeout=600
    )
    assert result.returncode == 2
    assert result.stderr.strip() == (
        f"redundancy: error: --scheduler {silent}: no Dask scheduler answered within 2 s; "
        "start one with `dask scheduler` and give its address, e.g. tcp://HOST:8786"
    )

    blocker = write(tmp_path, "file", "")
    result = run_cli("map", str(family), "--out", str(blocker / "maps"), timeout=600)
    assert result.returncode == 2
    assert result.stderr.strip().startswith(f"redundancy: error: --out {blocker / 'maps'}")
    assert len(result.stderr.strip().splitlines()) == 1


@contextlib.contextmanager
def listener(reply: bytes):
    """A TCP server on a free local port, in a thread, that accepts every connection and sends
    ``reply`` on it (nothing if empty); yields its address."""
    server = socket.create_server(("127.0.0.1", 0))
    accepted = []

    def serve():
        with contextlib.suppress(OSError):  # the server shut down
            while True:
                connection, _ = server.accept()
                accepted.append(connection)
                connection.sendall(reply)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        server.shutdown(socket.SHUT_RDWR)  # wakes the accept
        thread.join(timeout=5)
        server.close()
        for connection in accepted:
            connection.close()


@contextlib.contextmanager
def never_accepting():
    """A TCP server on a free local port that never accepts, its queue of connections already
    full, so that a new connection is never even completed; yields its address."""
    server = socket.create_server(("127.0.0.1", 0), backlog=0)
    queued = [socket.socket() for _ in range(2)]
    for client in queued:
        client.setblocking(False)
        client.connect_ex(server.getsockname())
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        for client in queued:
            client.close()
        server.close()


SILENT = ": no Dask scheduler answered within 1 s; start one"


@pytest.mark.parametrize(
    ("server", "expected"),
    [
        (functools.partial(listener, b""), SILENT),
        (never_accepting, SILENT),
        (
            functools.partial(listener, b"HTTP/1.1 400 Bad Request\r\n\r\n"),
            " does not answer as a Dask scheduler",
        ),
    ],
    ids=["silent", "never accepting", "another protocol"],
)
def test_a_server_that_is_no_scheduler_is_one_line_within_the_timeout(tmp_path, server, expected):
    """The timeout bounds the whole connection, handshake included: a server that accepts and
    stays silent, or never accepts, is one where no scheduler answered (not something else
    listening), and a server speaking another protocol is named as such."""
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2))
    with server() as address:  # the run's timeout guards a hang only
        result = run_cli(
            "map", str(family), "--scheduler", address, "--timeout", "1", cwd=tmp_path, timeout=600
        )
    assert result.returncode == 2
    assert result.stderr.startswith(f"redundancy: error: --scheduler {address}{expected}")
    assert len(result.stderr.splitlines()) == 1, result.stderr


def test_a_map_where_no_start_is_reachable_leaves_nothing_behind(tmp_path):
    """The failure is final: the chunk store goes, and the default output folder maps/ that
    the run made."""
    nowhere = write(
        tmp_path, "far.toml", WORKSPACE.format(chunk=2, nx=2).replace("[1.5, 4.0", "[40.0, 50.0")
    )
    result = run_cli("map", str(nowhere), "--workers", "1", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "none of its 6 problems is reachable" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.toml"]


def test_a_map_whose_scheduler_does_not_answer_leaves_nothing_behind(tmp_path):
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2))
    silent = f"tcp://127.0.0.1:{free_port()}"
    result = run_cli("map", str(family), "--scheduler", silent, "--timeout", "1", cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ws.toml"]


def test_bound_and_energy_columns_agree_with_the_searches_they_come_from(tmp_path, crane, client):
    """The bound is never above the improved start's peak; the energy figures are those of
    the best start's motion under each supply. An integral objective has no min-max bound,
    and its row says why and where its least value is found (its columns were empty)."""
    rows = design_map(
        write(
            tmp_path,
            "e.toml",
            'objectives = ["velocity", "ls_energy"]\nbound = true\nenergy = true\n'
            '[task]\nsegments = ["1-2", "3-1"]\n',
        ),
        client,
    )
    cycle = WorkCycle.from_toml(crane.task_file, dimension=crane.m)
    circuit = crane.circuit()
    pumped = rows[rows["objective"] == "ls_energy"]
    assert len(pumped) == 2 and pumped["bound_peak"].isna().all()
    for row in pumped.itertuples():
        search = improved_start(crane, cycle[row.segment], LS_ENERGY)
        assert row.motion_peak == pytest.approx(search.best_peak, rel=1e-9)
        assert "reduces its measure by 'integral'" in row.bound_reason
        assert "redundancy.integral_optimum" in row.bound_reason
    for row in rows[rows["objective"] == "velocity"].itertuples():
        assert row.feasible and pd.isna(row.bound_reason)
        motion = improved_start(crane, cycle[row.segment], VELOCITY).motion()
        assert row.motion_peak == pytest.approx(motion.peak_velocity_norm[0], rel=1e-9)
        assert row.bound_peak <= row.motion_peak * (1 + 1e-9)
        assert row.gap_pct == pytest.approx(
            100 * (row.motion_peak - row.bound_peak) / row.bound_peak
        )
        ls, cp = (
            motion.energy(s)[0] / 1e3 for s in (circuit.load_sensing, circuit.constant_pressure)
        )
        assert (row.ls_energy_kj, row.cp_energy_kj) == pytest.approx((ls, cp), rel=1e-9)
        assert row.peak_flow_lpm == pytest.approx(motion.flows.pump_flow[0].max() * 60e3, rel=1e-9)
        assert row.ls_energy_kj < row.cp_energy_kj  # the LS pump meets the load, CP its setting


def test_the_fingerprint_sees_every_point_of_a_long_path_and_nothing_cached():
    """Two families whose 2,000-point paths differ at one point in the middle (which numpy's
    repr elides) have different fingerprints; what a segment has computed and cached since
    (its timing) changes none, nor where its task file lies (a store survives a moved
    folder)."""
    x = np.linspace(1.5, 3.5, 2000)
    points = np.column_stack([x, 0.2 * np.sin(x)])
    bent = points.copy()
    bent[1000, 1] += 1e-6

    def family(path):
        segment = Segment.along("dig", Polyline(path), 0.5)
        return MapFamily("f", "hiab031", None, ("velocity",), ("x3",), (segment,))

    first = family(points)
    assert family(bent).fingerprint != first.fingerprint
    cached = family(points)
    cached.segments[0].duration  # noqa: B018 - caches the timing
    assert cached.fingerprint == first.fingerprint
    moved = Segment.along("dig", Polyline(points), 0.5, source="/elsewhere/task.toml: segments[0]")
    assert dataclasses.replace(first, segments=(moved,)).fingerprint == first.fingerprint


def test_a_chunks_problems_are_segments_times_the_design_grid_in_product_order():
    """Problem i is segment i // D with design i % D, the designs numbered as itertools.product
    numbers them (the last parameter fastest), whatever the chunk it falls in."""
    segments = tuple(
        Segment(name, np.array([x, -0.5]), np.array([x - 1, -0.5]), 0.5)
        for name, x in (("near", 3.0), ("far", 3.5))
    )
    grid = (("payload", (0.0, 50.0, 100.0)), ("speed", (0.2, 0.4)))
    family = MapFamily("f", "hiab031", None, ("velocity",), ("x3",), segments, grid, chunk=4)
    found = [problem for c in range(family.chunks) for problem in family.problems(c)]
    assert [i for i, _, _ in found] == list(range(len(family))) == list(range(12))
    expected = [
        (segment, Design(payload=payload, speed=speed))
        for segment in segments
        for payload, speed in itertools.product(*(values for _, values in grid))
    ]
    assert all(s is es and d == ed for (_, s, d), (es, ed) in zip(found, expected, strict=True))


def test_a_design_speed_keeps_the_segments_path_and_profile():
    """A speed on the design grid sets the segment's (peak) speed alone: an arc stays the arc,
    a trapezoidal profile stays trapezoidal, only faster."""
    arc = Arc.about([3.0, -0.5], [2.0, 0.5], [2.0, -0.5], "ccw")
    segment = Segment.along("arc", arc, 0.3, "trapezoidal", 0.5)
    family = MapFamily("f", "hiab031", None, ("velocity",), ("x3",), (segment,))
    faster = family.segment_for(segment, Design(speed=0.6))
    assert faster.shape is arc and faster.profile == "trapezoidal" and faster.speed == 0.6
    t = np.linspace(0.0, faster.duration, 7)
    np.testing.assert_allclose(np.linalg.norm(faster.position(t) - [2.0, -0.5], axis=1), 1.0)
    assert faster.duration < segment.duration


def _damage_truncated(path: Path, other: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _damage_emptied(path: Path, other: Path) -> None:
    path.write_bytes(b"")


def _damage_garbage(path: Path, other: Path) -> None:
    path.write_bytes(os.urandom(path.stat().st_size))


def _damage_foreign(path: Path, other: Path) -> None:
    path.write_bytes(other.read_bytes())  # another chunk's file, whole and valid Parquet


@pytest.mark.parametrize(
    "damage", [_damage_truncated, _damage_emptied, _damage_garbage, _damage_foreign]
)
def test_a_damaged_chunk_is_solved_again_with_one_line(tmp_path, client, damage):
    family = read_family(write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2)))
    store = tmp_path / "store"
    first = design_map(family, client, store=store)
    files = sorted(store.glob("chunk-*.parquet"))
    damage(files[1], files[0])
    untouched = {f.name: f.stat().st_ino for f in (files[0], files[2])}
    with pytest.warns(UserWarning) as noted:
        again = design_map(family, client, store=store)
    assert [str(w.message) for w in noted] == [
        f"map store {store}: {files[1].name} damaged: its checksum differs from the manifest's; "
        "solved again"
    ]
    pd.testing.assert_frame_equal(first, again)
    assert {f.name: f.stat().st_ino for f in (files[0], files[2])} == untouched
    with warnings.catch_warnings():  # the chunk solved again is vouched for from now on
        warnings.simplefilter("error")
        pd.testing.assert_frame_equal(first, design_map(family, client, store=store))


def test_a_chunk_file_the_manifest_does_not_name_is_solved_again(tmp_path, client):
    family = read_family(write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2)))
    store = tmp_path / "store"
    first = design_map(family, client, store=store)
    manifest = store / "chunks.jsonl"
    lines = manifest.read_text().splitlines()
    kept = [line for line in lines if '"chunk": 2,' not in line]
    assert len(kept) == len(lines) - 1
    manifest.write_text("\n".join(kept) + "\n")
    with pytest.warns(UserWarning, match="chunk-000002.parquet not in the store's manifest"):
        again = design_map(family, client, store=store)
    pd.testing.assert_frame_equal(first, again)


def test_a_manifest_line_whose_problems_differ_is_not_trusted(tmp_path, client):
    """A manifest that vouches for a chunk's file but names other problems (a store written for
    another chunk size under the same fingerprint cannot be, but a hand-edited one can)."""
    family = read_family(write(tmp_path, "ws.toml", WORKSPACE.format(chunk=2, nx=2)))
    store = tmp_path / "store"
    first = design_map(family, client, store=store)
    manifest = store / "chunks.jsonl"
    manifest.write_text(manifest.read_text().replace('"problems": [2, 3]', '"problems": [4, 5]'))
    with pytest.warns(UserWarning, match=r"chunk-000001.parquet holds problems \[4, 5\], not"):
        again = design_map(family, client, store=store)
    pd.testing.assert_frame_equal(first, again)


def test_a_scheduler_lost_mid_map_ends_in_one_line_and_keeps_the_finished_chunks(tmp_path):
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=1, nx=8))
    store = tmp_path / ".out.chunks"
    with dask_cluster(tmp_path, 1) as (address, started):
        command = ["map", str(family), "--scheduler", address, "--timeout", "2", "--quiet"]
        process = subprocess.Popen(
            [sys.executable, "-m", "redundancy.cli", *command, "--out", str(tmp_path / "out")],
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 600  # guards a hang only
        while len(list(store.glob("chunk-*.parquet"))) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        started[0].kill()  # the scheduler
        _, stderr = process.communicate(timeout=600)
    assert process.returncode == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("redundancy: error: map 'workspace': the Dask scheduler was lost")
    assert "its finished chunks are kept" in lines[0]
    kept = sorted(store.glob("chunk-*.parquet"))
    assert 2 <= len(kept) < 24
    out = str(tmp_path / "out")
    rerun = run_cli("map", str(family), "--workers", "1", "--out", out, terminal=True)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{len(kept)}/24" in rerun.stderr


def _workers(pid: int) -> list[int]:
    """The worker processes the process ``pid`` has started (multiprocessing's spawned
    children), read from /proc."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError):
            parent = int(stat.read_text().rpartition(")")[2].split()[1])
            if parent == pid and b"spawn_main" in (stat.parent / "cmdline").read_bytes():
                found.append(int(stat.parent.name))
    return found


def _catches_ctrl_c(pid: int) -> bool:
    """Whether the process ``pid`` has a handler of its own for SIGINT: in a worker, Python
    has started and is loading distributed (the workers of a map never ignore it)."""
    with contextlib.suppress(OSError):
        status = Path(f"/proc/{pid}/status").read_text()
        caught = next(line for line in status.splitlines() if line.startswith("SigCgt:"))
        return bool(int(caught.split()[1], 16) & 1 << (signal.SIGINT - 1))
    return False


def _alive(pid: int) -> bool:
    """Whether the process ``pid`` still runs (an exited one waiting to be reaped does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


@pytest.mark.parametrize("moment", ["workers starting", "solving"])
def test_ctrl_c_to_a_local_maps_process_group_ends_in_one_line(tmp_path, moment):
    """A Ctrl-C at a terminal reaches the command and its local workers alike, whether they
    are still starting (loading distributed) or solving: the command alone answers, in one
    line, and closes them before it exits; the output folder is not made. A Ctrl-C while the
    workers started used to print their tracebacks and distributed's, and to leave them
    running after the command (about 2 s, until they saw their parent gone)."""
    # 120 one-problem chunks: the map is still running when its first chunk is seen, however
    # slowly this test is scheduled (a finished map removes its store, and the signal would
    # then reach a command that already succeeded)
    family = write(tmp_path, "ws.toml", WORKSPACE.format(chunk=1, nx=40))
    store = tmp_path / ".out.chunks"
    command = ["map", str(family), "--workers", "2", "--out", str(tmp_path / "out"), "--quiet"]
    process = subprocess.Popen(
        [sys.executable, "-m", "redundancy", *command],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=as_foreground,
    )

    def ready() -> bool:
        if moment == "solving":
            return bool(list(store.glob("chunk-*.parquet")))
        # a worker's Python runs: it loads distributed for about a second
        return any(_catches_ctrl_c(pid) for pid in _workers(process.pid))

    deadline = time.monotonic() + 600  # guards a hang only
    while not ready() and time.monotonic() < deadline:
        assert process.poll() is None, f"the map ended before {moment} was seen"
        time.sleep(0.01)
    # the group is frozen while the test makes sure the map is still solving, so that the
    # Ctrl-C, delivered as the group goes on, cannot reach a map that has meanwhile finished
    os.killpg(process.pid, signal.SIGSTOP)
    try:
        solved = len(list(store.glob("chunk-*.parquet")))
        assert process.poll() is None and solved < 120, f"{solved} chunks at the signal"
        workers = _workers(process.pid)
        assert workers and ready()
        os.killpg(process.pid, signal.SIGINT)
    finally:
        os.killpg(process.pid, signal.SIGCONT)
    _, stderr = process.communicate(timeout=600)
    assert process.returncode == 130, stderr
    assert stderr == "redundancy: interrupted\n"
    assert not [pid for pid in workers if _alive(pid)], "workers outlived the command"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.chunks", "ws.toml"]
    if moment == "solving":
        assert list(store.glob("chunk-*.parquet"))
