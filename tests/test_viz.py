"""Playback: the drawing against the actuator map, the standalone page in a real browser, and
the live server's clean exit."""

import base64
import itertools
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import browser
import meshcat
import numpy as np
import pinocchio as pin
import pytest
import umsgpack
import zmq
from lxml import html
from PIL import Image
from sampling import random_configurations

from redundancy import actuator_space, load_robot
from redundancy.cli import main
from redundancy.planning.ik import configuration_at
from redundancy.planning.integrate import simulate
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import VELOCITY
from redundancy.viz.playback import (
    BACKGROUND,
    COLOURS,
    FIELD_OF_VIEW,
    FRAME_RATE,
    LIMIT_MARGIN,
    Playback,
    Recording,
    export_html,
    quaternions,
)

START = ["--robot", "hiab031", "--segment", "1-2", "--objective", "velocity", "--x3init", "1.0"]


@pytest.fixture(scope="module")
def motion(crane):
    """Segment 1-2 from x3init = 1.0 m under the unweighted pseudoinverse (5 s)."""
    segment = WorkCycle.from_toml(crane.task_file, dimension=crane.m)["1-2"]
    q = configuration_at(crane, segment.start, {"x3": 1.0})
    return simulate(crane, VELOCITY.resolver, segment, q[None])


def recorded(motion):
    """A playback drawn into a visualizer that records its commands instead of sending them."""
    recording = Recording()
    vis = meshcat.Visualizer(window=recording)
    playback = Playback(motion)
    playback.draw(vis)
    return playback, vis, recording


def decoded(commands):
    return [umsgpack.unpackb(c) for c in commands]


def cylinder_path(name, part):
    return f"/meshcat/playback/cylinders/{name}/{part}"


def posed(playback, q):
    """The transforms (4, 4) the drawn scene takes at configuration ``q`` (n,), by the node
    paths meshcat knows them by."""
    placed, _ = playback.placements(q[None])
    return {f"/meshcat/playback/{path}": poses[0] for path, poses in placed.items()}


def test_drawn_cylinder_length_equals_the_actuator_value(crane, motion):
    """From the barrel's far end to the rod's far end, as sent to meshcat (a cylinder's axis is
    its local y), each cylinder is x_i long: Eq. (9) through the actuator map."""
    playback, _, recording = recorded(motion)
    heights = {
        c["path"]: c["object"]["geometries"][0]["height"]
        for c in decoded(recording.commands)
        if c["type"] == "set_object" and "/cylinders/" in c["path"]
    }
    assert len(heights) == 4
    q = random_configurations(crane, 30, seed=41)
    x = actuator_space(crane, q).x
    for qi, xi in zip(q, x):
        poses = posed(playback, qi)
        for row, name in enumerate(["x1", "x2"]):
            barrel, rod = (cylinder_path(name, part) for part in ("barrel", "rod"))
            far_barrel = poses[barrel][:3, 3] - poses[barrel][:3, 1] * heights[barrel] / 2
            far_rod = poses[rod][:3, 3] + poses[rod][:3, 1] * heights[rod] / 2
            assert np.linalg.norm(far_rod - far_barrel) == pytest.approx(xi[row], abs=1e-12)
            assert np.allclose(poses[barrel][:3, 1], poses[rod][:3, 1], atol=1e-12)


def test_drawn_bucket_linkage_closes_at_its_declared_pins():
    """The excavator's bucket drive: the cylinder spans x_bucket, the rocker turns about its
    pivot on the stick, the coupler ends at its pin on the bucket, and rocker, coupler and rod
    meet at one pin, at every shown configuration."""
    excavator = load_robot("excavator")
    segment = WorkCycle.from_toml(excavator.task_file, dimension=excavator.m)["1-2"]
    q = configuration_at(excavator, segment.start, {"bucket": 1.3})
    playback, _, recording = recorded(simulate(excavator, VELOCITY.resolver, segment, q[None]))
    linkage = excavator.actuators["bucket"]
    heights = {
        c["path"]: c["object"]["geometries"][0]["height"]
        for c in decoded(recording.commands)
        if c["type"] == "set_object" and re.search("/(cylinders|linkages)/", c["path"])
    }
    bars = [f"/meshcat/playback/linkages/bucket/{bar}" for bar in ("rocker", "coupler")]
    assert [heights[b] for b in bars] == pytest.approx([linkage.rocker[2], linkage.coupler[2]])
    model, data = excavator.model, excavator.model.createData()
    for qi in random_configurations(excavator, 10, seed=43):
        poses = posed(playback, qi)

        def ends(path, poses=poses):
            centre, axis = poses[path][:3, 3], poses[path][:3, 1] * heights[path] / 2
            return centre - axis, centre + axis

        barrel, rod = (cylinder_path("bucket", part) for part in ("barrel", "rod"))
        base, pin_joint = ends(barrel)[0], ends(rod)[1]
        x = actuator_space(excavator, qi).x[0, excavator.actuators.names.index("bucket")]
        assert np.linalg.norm(pin_joint - base) == pytest.approx(x, abs=1e-12)
        pin.framesForwardKinematics(model, data, qi)
        pivot, coupler_pin = (
            data.oMf[model.getFrameId(link)].act(point)
            for link, point in (linkage.rocker[:2], linkage.coupler[:2])
        )
        rocker, coupler = (ends(path) for path in bars)
        np.testing.assert_allclose(rocker, [pivot, pin_joint], atol=1e-12)
        np.testing.assert_allclose(coupler, [pin_joint, coupler_pin], atol=1e-12)


def test_a_cylinder_is_at_its_limit_past_its_stroke_and_not_inside_it(crane, motion):
    """Of two configurations, one with x1 inside its stroke and one with x1 past its lower
    end, only the second has x1's cylinder at its limit (the animation turns it red there)."""
    playback, _, _ = recorded(motion)
    middle = (crane.lower + crane.upper) / 2
    past = middle.copy()
    past[0] = crane.lower[0] - 0.05
    x = actuator_space(crane, np.array([middle, past])).x
    assert crane.actuators.lower[0] < x[0, 0] < crane.actuators.upper[0]
    assert x[1, 0] < crane.actuators.lower[0]
    _, limited = playback.placements(np.array([middle, past]))
    assert [c.name for c in playback.cylinders] == ["x1", "x2"]
    assert limited.tolist() == [[False, False], [True, False]]


def rotations(count, seed):
    """Random rotations (k, 4, 4) by uniform unit quaternions, half of them turned by nearly
    or exactly 180° (w within 1e-9 of 0, or 0), where the quaternion's sign is a choice."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(count, 4))
    q[: count // 4, 3] = rng.uniform(-1e-9, 1e-9, count // 4)
    q[count // 4 : count // 2, 3] = 0.0
    x, y, z, w = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    T = np.tile(np.eye(4), (count, 1, 1))
    T[:, :3, :3] = np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)
    T[:, :3, 3] = rng.normal(size=(count, 3))
    return T


def test_batch_quaternions_are_meshcats_one_matrix_at_a_time():
    """For rotations of every angle, 180° ones included, and for the scaled transforms
    Pinocchio's visualizer sends for scaled meshes, the batch gives meshcat's quaternion: the
    same, w ≥ 0, and at 180° (w = 0, where q and −q are both meshcat's choice to make) the
    same up to sign."""
    T = rotations(400, seed=47)
    T = np.concatenate([T, T[:50] @ np.diag([0.5, 2.0, 1.5, 1.0]), np.eye(4)[None]])
    theirs = np.array([meshcat.animation.js_quaternion(matrix) for matrix in T])
    assert np.abs(theirs[100:200, 3]).max() < 1e-9  # the 180° rotations are there
    ours = quaternions(T)
    turned = np.r_[100:200]
    kept = np.setdiff1d(np.arange(len(T)), turned)
    np.testing.assert_allclose(ours[kept], theirs[kept], rtol=0, atol=1e-12)
    signs = np.sign(np.sum(ours[turned] * theirs[turned], axis=1, keepdims=True))
    np.testing.assert_allclose(ours[turned], signs * theirs[turned], rtol=0, atol=1e-12)
    assert (ours[:, 3] >= 0).all()


def test_the_animation_keys_each_frame_as_the_scene_shows_it(crane, motion):
    """At every shown sample, each animated node's position and quaternion are those of the
    transform the scene takes at that configuration, and each cylinder part's colour is red
    exactly where its length is within the margin of a stroke limit."""
    playback, vis, _ = recorded(motion)
    clips = {a["path"]: a["clip"] for a in playback.animation(vis).lower()}
    x = actuator_space(crane, playback.q[playback.samples]).x
    names = crane.actuators.names
    for frame in range(0, len(playback.samples), 7):
        poses = posed(playback, playback.q[playback.samples[frame]])
        # 4 links, the column (a hull), 2 brackets, 2 cylinders of 2 parts
        assert len(poses) == 11
        for path, T in poses.items():
            keys = {t["name"]: t["keys"][frame]["value"] for t in clips[path]["tracks"]}
            np.testing.assert_allclose(keys[".position"], T[:3, 3], rtol=0, atol=1e-12)
            quaternion = meshcat.animation.js_quaternion(T)
            np.testing.assert_allclose(keys[".quaternion"], quaternion, rtol=0, atol=1e-12)
        for name in ("x1", "x2"):
            actuator, value = crane.actuators[name], x[frame, names.index(name)]
            red = min(value - actuator.lower, actuator.upper - value) <= LIMIT_MARGIN
            for part in ("barrel", "rod"):
                track = clips[cylinder_path(name, part) + "/<object>"]["tracks"][0]
                colour = COLOURS["limit" if red else part]
                expected = [((colour >> shift) & 0xFF) / 255 for shift in (16, 8, 0)]
                assert track["name"] == ".material.color"
                assert track["keys"][frame]["value"] == pytest.approx(expected, abs=1e-15)


def test_a_pin_off_its_link_s_mesh_is_held_by_a_bracket_that_moves_with_it(crane, motion):
    """The lift cylinder's base beside the column and the fold cylinder's base below boom 1 lie
    off their links' boxes, and floated: each has a bracket from the pin, where the cylinder's
    end is at every shown pose, to the nearest point of its link's box."""
    playback, _, _ = recorded(motion)
    assert sorted(playback.brackets) == ["x1_base", "x2_base"]
    kinematics = crane.kinematics(playback.q[playback.samples])
    for name, (_, points) in playback.brackets.items():
        actuator = crane.actuators[name.split("_")[0]]
        base = actuator.ends(kinematics)[0]
        poses = playback.placements(playback.q[playback.samples])[0][f"links/brackets/{name}"]
        pins = poses[:, :3, :3] @ points[0] + poses[:, :3, 3]
        np.testing.assert_allclose(pins, base, rtol=0, atol=1e-12)
        assert np.linalg.norm(points[1] - points[0]) > 0.1  # m: well off the box


def test_a_bracket_reaches_a_scaled_mesh_as_it_reaches_the_box_it_draws(crane, tmp_path):
    """The crane's boxes drawn as a unit cube's mesh scaled to each box: a mesh's bounding box
    as loaded holds its scale, and the brackets are the boxes' (scaled twice, every pin lay
    off its shrunken mesh and had one)."""
    from redundancy.viz.playback import _visual_model, brackets

    corners = list(itertools.product((-0.5, 0.5), repeat=3))
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1)]
    faces += [(2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    facets = "".join(
        "facet normal 0 0 0\nouter loop\n"
        + "".join(f"vertex {x} {y} {z}\n" for x, y, z in (corners[i] for i in face))
        + "endloop\nendfacet\n"
        for face in faces
    )
    (tmp_path / "cube.stl").write_text(f"solid cube\n{facets}endsolid cube\n")
    urdf = re.sub(
        r'<box size="([^"]+)"/>',
        r'<mesh filename="cube.stl" scale="\1"/>',
        crane.urdf.read_text(),
    )
    (tmp_path / "crane.urdf").write_text(urdf)
    shutil.copy(crane.urdf.parent / "robot.toml", tmp_path)
    toml = (tmp_path / "robot.toml").read_text()
    toml = toml.replace('urdf = "hiab031.urdf"', 'urdf = "crane.urdf"')
    (tmp_path / "robot.toml").write_text(toml.replace('task = "task.toml"', ""))
    meshed = load_robot(tmp_path / "robot.toml")
    boxes = brackets(crane, _visual_model(crane)[0])
    meshes = brackets(meshed, _visual_model(meshed)[0])
    assert sorted(meshes) == sorted(boxes) == ["x1_base", "x2_base"]
    for name, (joint, points) in boxes.items():
        assert meshes[name][0] == joint
        np.testing.assert_allclose(meshes[name][1], points, rtol=0, atol=1e-9)


def test_a_recorded_page_holds_the_bytes_meshcats_encoder_gives(motion):
    """Every command of a drawn and animated scene (typed arrays of the traced path
    included) is encoded byte for byte as meshcat's own encoder encodes it."""
    playback, vis, recording = recorded(motion)
    lowered = []
    kept = recording.send

    def send(command):
        lowered.append(command.lower())
        kept(command)

    recording.send = send
    playback.draw(vis)
    vis.set_animation(playback.animation(vis), play=True, repetitions=1)
    sent = recording.commands[-len(lowered) :]
    assert [c["type"] for c in lowered].count("set_animation") == 1
    traced = next(c for c in lowered if c["path"].endswith("/traced"))
    assert isinstance(
        traced["object"]["geometries"][0]["data"]["attributes"]["position"]["array"], umsgpack.Ext
    )
    assert sent == [umsgpack.packb(c) for c in lowered]


def page_commands(page):
    """The commands a page replays, decoded."""
    listing = re.search(r"for \(const command of \[(.*?)\]\)", page, re.DOTALL).group(1)
    return [umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'"([^"]+)"', listing)]


def test_html_export_runs_without_a_server_and_holds_the_animation(
    motion, tmp_path, monkeypatch, capsys
):
    """The command writes the page with no process started and no socket opened; the page
    replays the scene and one animation keyed at the motion's times, at most 30 a second,
    and loads nothing."""

    def refuse(*args, **kwargs):
        raise AssertionError("the export must not start a server or open a socket")

    monkeypatch.setattr(subprocess, "Popen", refuse)
    monkeypatch.setattr(zmq.Context, "socket", refuse)
    path = tmp_path / "crane.html"
    assert main(["play", *START, "--html", str(path)]) == 0
    assert f"playback: {path}" in capsys.readouterr().out

    page = path.read_text()
    commands = page_commands(page)
    animations = [c for c in commands if c["type"] == "set_animation"]
    assert len(animations) == 1 and animations[0]["options"]["play"]
    clips = {a["path"]: a["clip"] for a in animations[0]["animations"]}
    links = [p for p in clips if "/links/visuals/" in p]
    assert len(links) == 4
    assert {cylinder_path(n, p) for n in ("x1", "x2") for p in ("barrel", "rod")} <= set(clips)
    shown = motion.t[0, Playback(motion).samples]
    assert shown[0] == 0 and shown[-1] == motion.t[0, -1] == pytest.approx(5.0)
    assert np.diff(shown)[:-1].min() >= 1 / FRAME_RATE
    for clip in clips.values():
        for track in clip["tracks"]:
            times = [key["time"] / clip["fps"] for key in track["keys"]]
            np.testing.assert_allclose(times, shown, rtol=0, atol=1e-12)
    assert "<script src" not in page and "<link" not in page and "viewer.connect" not in page
    # The viewer script names XHTML's namespace, and a socket address in the connect method
    # that the page never calls.
    addresses = set(re.findall(r"(?:https?|wss?)://[^\s\"'`)]*", page))
    assert addresses <= {"http://www.w3.org/1999/xhtml", "ws://${location.host}"}


def test_study_writes_a_playback_per_segment_for_the_best_start(tmp_path, capsys):
    """One page per segment with a feasible best start; none where there is no best."""
    task = tmp_path / "short.toml"
    task.write_text(
        'segments = ["1-2", "2-1"]\nheld = ["x3"]\n[points]\n1 = [3.5, -0.5]\n2 = [3.2, -0.5]\n'
    )
    out = tmp_path / "out"
    args = ["study", "--task", str(task), "--objective", "velocity", "--samples", "3"]
    args += ["--method", "sweep", "--cycles", "0"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    segments = json.loads((out / "report.json").read_text())["studies"][0]["segments"]
    best = [s["name"] for s in segments if s["best"] is not None]
    assert best == ["1-2"]  # with 3 samples, no start of 2-1 stays inside the limits
    pages = sorted(p.name for p in out.glob("playback_*.html"))
    assert pages == [f"playback_velocity_{name}.html" for name in best]
    printed = capsys.readouterr().out
    assert f"playbacks: {out / pages[0]}" in printed
    assert f"start here: {out / 'index.html'}" in printed and (out / "index.html").is_file()
    for page in pages:
        commands = page_commands((out / page).read_text())
        assert [c["type"] for c in commands].count("set_animation") == 1


def screenshots(page, times, folder):
    """Headless Chromium's screenshots of ``page`` paused at each time (s), RGB (H, W, 3)."""
    runs, shots = [], []
    for i, t in enumerate(times):
        shot = folder / f"shot{i}.png"
        options = ["--virtual-time-budget=3000", f"--screenshot={shot}"]
        command = browser.command(f"{page.as_uri()}?t={t}", folder / f"profile{i}", *options)
        runs.append(subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE))
        shots.append(shot)
    for run in runs:
        _, errors = run.communicate(timeout=600)
        assert run.returncode == 0, errors.decode()[-2000:]
    return [np.asarray(Image.open(shot).convert("RGB")).astype(int) for shot in shots]


def pixel(playback, point, size):
    """Where the camera shows a world point (3,) in a (width, height) image: (column, row)."""
    offset = point - playback.aim
    right = np.cross([0.0, 0.0, 1.0], playback.view)
    right /= np.linalg.norm(right)
    up = np.cross(playback.view, right)
    depth = playback.distance - offset @ playback.view
    focal = size[1] / 2 / np.tan(np.radians(FIELD_OF_VIEW) / 2)
    return (
        round(size[0] / 2 + focal * (offset @ right) / depth),
        round(size[1] / 2 - focal * (offset @ up) / depth),
    )


def test_exported_page_draws_the_crane_and_animates_it_in_a_browser(crane, motion, tmp_path):
    """Screenshots at t = 0 and 4 s: the column stands where the camera puts it, the booms are
    drawn, and the two frames differ where the crane moved."""
    page = export_html(motion, tmp_path / "crane.html")
    first, later = screenshots(page, [0.0, 4.0], tmp_path)
    background = np.round(np.array(BACKGROUND) * 255)
    drawn = [np.abs(shot - background).max(axis=2) > 24 for shot in (first, later)]

    data = crane.model.createData()
    pin.framesForwardKinematics(crane.model, data, motion.q[0, 0])
    column = data.oMf[crane.model.getFrameId("column")].translation * [1, 1, 0.5]
    col, row = pixel(Playback(motion), column, (first.shape[1], first.shape[0]))
    for mask in drawn:
        assert mask[row - 8 : row + 9, col - 8 : col + 9].mean() > 0.9
        assert 0.03 < mask.mean() < 0.5
    changed = np.abs(first - later).max(axis=2) > 24
    assert changed.mean() > 0.02


def test_the_page_shows_the_time_and_each_actuator_red_at_its_stroke_limit(crane, tmp_path):
    """From x3init at the top of x3's stroke: after virtual time, at t = 0 the page's clock
    reads "t = 0.00 s" and x3's gauge is red and says why; at t = 4 s x3 is back inside its
    stroke and no gauge is red. Every gauge gives its actuator's value and speed in mm, as the
    command line does."""
    segment = WorkCycle.from_toml(crane.task_file, dimension=crane.m)["1-2"]
    q = configuration_at(crane, segment.start, {"x3": crane.actuators["x3"].upper})
    motion = simulate(crane, VELOCITY.resolver, segment, q[None])
    page = export_html(motion, tmp_path / "limit.html")
    playback = Playback(motion)
    for t, red in ((0.0, {"x3"}), (4.0, set())):
        shown = html.fromstring(
            browser.dom(f"{page.as_uri()}?t={t}", tmp_path / f"{t}", "--virtual-time-budget=3000")
        )
        assert shown.get_element_by_id("clock").text_content() == f"t = {t:.2f} s"
        heading = shown.get_element_by_id("heading").text_content()
        assert heading == f"hiab031: segment 1-2, {VELOCITY.resolver.name}"
        i = playback.samples[np.searchsorted(playback.t[playback.samples], t + 1e-6) - 1]
        at_limit = set()
        for row, name in zip(
            shown.xpath("//div[@class='gauge']"), crane.actuators.names, strict=True
        ):
            label, _, value, stroke = row.xpath("span")  # name, gauge, value, stroke's ends
            j = crane.actuators.names.index(name)
            assert label.text_content() == name
            ends = crane.actuators[name].lower, crane.actuators[name].upper
            assert stroke.text_content() == f"stroke [{1e3 * ends[0]:.1f}, {1e3 * ends[1]:.1f}] mm"
            # the page's values (rounded to 10 µm) in mm; a rounded −0 is 0, as on the page
            at, rate = (np.round(v[0, i, j], 5) * 1e3 for v in (motion.x, motion.x_dot))
            assert value.text_content().startswith(f"{at:z.1f} mm, ẋ = {rate:z.1f} mm/s")
            if "at-limit" in value.get("class", ""):
                assert value.text_content().endswith("at its stroke limit")
                at_limit.add(name)
        assert at_limit == red


def children(pid):
    """Processes whose parent is ``pid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def listening_ports(pid=None, addresses=None):
    """TCP ports in the LISTEN state, of the process ``pid`` or of any; with ``addresses``
    (a set), the local addresses they are bound to are added to it ("127.0.0.1", "0.0.0.0", or
    an IPv6 address in /proc's hex)."""
    inodes = None
    if pid is not None:
        links = [os.readlink(fd) for fd in Path(f"/proc/{pid}/fd").iterdir()]
        inodes = {link[8:-1] for link in links if link.startswith("socket:[")}
    ports = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and (inodes is None or fields[9] in inodes):
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
                if addresses is not None:
                    address = fields[1].rsplit(":", 1)[0]
                    if len(address) == 8:  # IPv4, little-endian hex
                        address = ".".join(str(b) for b in reversed(bytes.fromhex(address)))
                    addresses.add(address)
    return ports


def launched_play(*options):
    """``redundancy play`` serving the test motion, and a watchdog that kills it after 60 s."""
    run = subprocess.Popen(
        [sys.executable, "-m", "redundancy.cli", "play", *START, *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    watchdog = threading.Timer(60, run.kill)
    watchdog.start()
    return run, watchdog


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads processes from /proc")
@pytest.mark.parametrize(
    "stop", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=["ctrl-c", "terminate", "kill"]
)
def test_live_playback_answers_on_localhost_and_leaves_nothing_behind(stop):
    """The page answers on 127.0.0.1, and only there; however play ends, even by SIGKILL, its
    server is gone and its ports are free within 2 s (the test kills only its own process)."""
    run, watchdog = launched_play()
    try:
        line = run.stdout.readline()
        address = re.search(r"http://127\.0\.0\.1:(\d+)/static/", line)
        assert address, line + run.stderr.read()
        servers = children(run.pid)
        assert len(servers) == 1
        bound: set[str] = set()
        ports = listening_ports(servers[0], bound)
        assert int(address.group(1)) in ports
        assert bound == {"127.0.0.1"}
        with urllib.request.urlopen(address.group(0), timeout=10) as response:
            assert response.status == 200
            assert b"<title>hiab031: segment 1-2</title>" in response.read()
        run.send_signal(stop)
        _, errors = run.communicate(timeout=600)
    finally:
        watchdog.cancel()
        run.kill()
    if stop == signal.SIGKILL:
        assert run.returncode == -signal.SIGKILL
    else:
        status, word = (130, "interrupted") if stop == signal.SIGINT else (143, "terminated")
        assert run.returncode == status and word in errors and "Traceback" not in errors
    deadline = time.monotonic() + 600  # guards a hang only: the server's reaping may lag
    while Path(f"/proc/{servers[0]}").exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    state = Path(f"/proc/{servers[0]}/stat")
    assert not state.exists() or state.read_text().rsplit(")", 1)[1].split()[0] == "Z"
    assert not ports & listening_ports()


def test_the_live_page_explains_itself_as_the_exported_one_does(crane, motion, tmp_path):
    """The page ``play`` serves, opened at ``?t=4`` in Chromium: after virtual time the
    animation the server sent has arrived, so the clock reads "t = 4.00 s" and each gauge
    gives its actuator's value and speed in m at that instant; the tab is titled after the
    robot and segment, the heading says what the command line said it plays (objective and
    start), play and the time slider are on the page, and the grid's spacing is stated."""
    run, watchdog = launched_play()
    try:
        line = run.stdout.readline()
        address = re.search(r"http://127\.0\.0\.1:\d+/static/", line)
        assert address, line + run.stderr.read()
        served = browser.dom(f"{address.group(0)}?t=4", tmp_path, "--virtual-time-budget=3000")
    finally:
        watchdog.cancel()
        run.terminate()
        run.communicate(timeout=600)
    shown = html.fromstring(served)
    assert shown.findtext(".//title") == "hiab031: segment 1-2"
    heading = shown.get_element_by_id("heading").text_content()
    said = line.split(": open ")[0]  # "segment 1-2, velocity objective, default start, x3 = …"
    assert said.startswith("segment 1-2, velocity objective, ") and heading == f"hiab031: {said}"
    assert shown.get_element_by_id("clock").text_content() == "t = 4.00 s"
    assert shown.get_element_by_id("play").text_content() == "play"  # paused at the instant
    assert shown.get_element_by_id("slider").get("type") == "range"
    playback = Playback(motion)
    assert shown.get_element_by_id("scale").text_content() == f"grid squares {playback.spacing:g} m"
    i = playback.samples[np.searchsorted(playback.t[playback.samples], 4.0 + 1e-6) - 1]
    rows = shown.xpath("//div[@class='gauge']")
    for row, name in zip(rows, crane.actuators.names, strict=True):
        label, _, value, stroke = row.xpath("span")
        j = crane.actuators.names.index(name)
        assert label.text_content() == name
        ends = crane.actuators[name].lower, crane.actuators[name].upper
        assert stroke.text_content() == f"stroke [{1e3 * ends[0]:.1f}, {1e3 * ends[1]:.1f}] mm"
        at, rate = (np.round(v[0, i, j], 5) * 1e3 for v in (motion.x, motion.x_dot))
        assert value.text_content().startswith(f"{at:z.1f} mm, ẋ = {rate:z.1f} mm/s")


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads processes from /proc")
def test_live_playback_opens_to_the_network_only_when_asked():
    """With ``--listen 0.0.0.0`` the page is served on every interface; meshcat's ZeroMQ
    socket stays on 127.0.0.1."""
    run, watchdog = launched_play("--listen", "0.0.0.0")
    try:
        line = run.stdout.readline()
        address = re.search(r"http://0\.0\.0\.0:(\d+)/static/", line)
        assert address, line + run.stderr.read()
        (server,) = children(run.pid)
        bound: set[str] = set()
        listening_ports(server, bound)
        assert bound == {"0.0.0.0", "127.0.0.1"}
        page = f"http://127.0.0.1:{address.group(1)}/static/"
        with urllib.request.urlopen(page, timeout=10) as response:
            assert response.status == 200
    finally:
        watchdog.cancel()
        run.terminate()
        run.communicate(timeout=600)


def test_with_two_held_actuators_the_peak_figure_is_a_map_over_their_box(tmp_path, request):
    """r = 2 (the crane's horizontal task, x2 and x3 held): Fig. 4a is one panel per segment
    over the stroke box, every reachable sample where it was taken, coloured by its peak when
    feasible, the feasible set's edge drawn, and the best start starred."""
    from matplotlib.collections import PathCollection

    from redundancy import WorkCycle, load_robot, run_study
    from redundancy.study.study import write_report
    from redundancy.viz.plots import peak_map_figure, pyplot, write_figures
    from redundancy.viz.report import write_index

    robot = load_robot("hiab031", task_axes="x")
    task = tmp_path / "line.toml"
    task.write_text('segments = ["a-b", "b-c"]\nheld = ["x2", "x3"]\n[points]\na = [3.0]\n'
                    "b = [2.0]\nc = [2.8]\n")  # fmt: skip
    cycle = WorkCycle.from_toml(task, dimension=1)
    study = run_study(robot, cycle, (VELOCITY,), samples=24, bound=False, progress=False, cycles=0)
    searches = study.searches["velocity"]
    figure = peak_map_figure(study.sweeps["velocity"], "peak", searches)
    request.addfinalizer(lambda: pyplot().close(figure))
    panes = [a for a in figure.axes if a.get_label() != "<colorbar>"]
    assert len(panes) == len(cycle.segments)
    for pane, sweep, search in zip(panes, study.sweeps["velocity"], searches):
        held = [robot.actuators[h] for h in ("x2", "x3")]
        assert pane.get_xlim() == (held[0].lower, held[0].upper)
        assert pane.get_ylim() == (held[1].lower, held[1].upper)
        dots = [c for c in pane.collections if isinstance(c, PathCollection)]
        feasible = [s for s in sweep.samples if s.feasible]
        coloured = dots[0]
        np.testing.assert_allclose(coloured.get_offsets(), [s.values for s in feasible])
        np.testing.assert_allclose(coloured.get_array(), [s.peak for s in feasible])
        reachable = [s for s in sweep.samples if s.peak is not None]
        assert len(dots[1].get_offsets()) == len(reachable) - len(feasible)
        if feasible and len(feasible) < len(reachable):
            assert len(pane.collections) > 2  # the feasible set's edge
        star = [line for line in pane.lines if line.get_marker() == "*"]
        assert search.best is not None
        np.testing.assert_allclose(np.ravel(star[0].get_xydata()), search.best.values)
    paths = write_figures(study, tmp_path)
    assert (tmp_path / "fig4a_peak_velocity.png") in paths
    write_report(study, tmp_path / "report.json")  # its index gives each held actuator's start
    page = write_index(tmp_path).read_text()
    best = ", ".join(f"{v:.4g}" for v in searches[0].best.values)
    assert "<td>x2, x3</td>" in page and f"<td>{best}</td>" in page


def test_every_axis_of_the_study_figures_names_its_unit(crane, request):
    """Each figure of a study with its cycle section: every axis label ends with its unit in
    brackets (a cycle count and colour bars aside); Fig. 4c shares Fig. 4b's velocity scale;
    Fig. 5a's legend names the segments with no feasible start and explains its encodings."""
    from matplotlib.legend import Legend

    from redundancy import ENERGY, WorkCycle, run_study
    from redundancy.viz.plots import pyplot, study_figures

    cycle = WorkCycle.from_toml(crane.task_file, dimension=crane.m)
    study = run_study(
        crane, cycle, (VELOCITY, ENERGY), samples=8, bound=False, progress=False, cycles=2
    )
    figures = study_figures(study)
    request.addfinalizer(lambda: [pyplot().close(figure) for figure in figures.values()])
    assert {"cycle_strokes.png", "cycle_drift.png", "hydraulics_best_velocity_1-2.png"} <= set(
        figures
    )
    for name, figure in figures.items():
        for axes in figure.axes:
            if axes.get_label() == "<colorbar>":
                continue
            for label in (axes.get_xlabel(), axes.get_ylabel()):
                assert label in ("", "cycle") or re.search(r"\(.+\)$", label), (name, label)
    workspace = figures["workspace.png"].axes[0]
    drawn = [line.get_xydata() for line in workspace.get_lines() if len(line.get_xydata())]
    for segment in cycle.segments:  # each path, in the task plane (world x, z)
        assert any(np.allclose(d, segment.outline()) for d in drawn), segment.name
    velocity = {n: m for (o, n), m in study.best_motions.items() if o == "velocity"}
    assert velocity
    for name, best in velocity.items():
        kinematics = crane.kinematics(best.q[0, :1])  # the machine at the best start
        for actuator in crane.actuators:
            if hasattr(actuator, "ends"):
                ends = np.array([p[0, [0, 2]] for p in actuator.ends(kinematics)])
                assert any(np.allclose(d, ends, atol=1e-9) for d in drawn), (name, actuator)
    for key, rods in study.best_poses.items():  # the links: a chain ending at the tool
        tool = crane.tool(crane.kinematics(study.best_motions[key].q[0, :1])).position[0]
        np.testing.assert_allclose(rods[-1, 1], tool, atol=1e-12)
        np.testing.assert_allclose(rods[1:, 0], rods[:-1, 1], atol=1e-12)  # a serial crane
        if key[0] == "velocity":
            for a, b in rods[:, :, [0, 2]]:
                assert any(np.allclose(d, [a, b], atol=1e-12) for d in drawn), key
    (cloud,) = [c for c in workspace.collections if len(c.get_offsets())]
    assert np.array_equal(cloud.get_offsets(), study.reachable[:, :2])  # the study's, as sampled
    for segment in cycle.segments:  # the paper's task lies inside the sampled reachable area
        path = segment.outline()
        gaps = np.linalg.norm(path[:, None] - study.reachable[None, :, :2], axis=-1).min(axis=1)
        assert gaps.max() < 0.1, segment.name
    optimal, other = (figures[f"fig4{k}_velocity_1-2.png"] for k in ("b_best", "c_nonoptimal"))
    assert optimal.axes[1].get_ylim() == other.axes[1].get_ylim()
    peaks = figures["fig5a_peak_energy.png"].axes[0]
    legends = [a for a in peaks.get_children() if isinstance(a, Legend)]
    said = [text.get_text() for legend in legends for text in legend.get_texts()]
    infeasible = [s.segment.name for s in study.sweeps["energy"] if not s.feasible]
    assert infeasible and all(f"segment {n}: no feasible start" in said for n in infeasible)
    assert {"every reachable start", "keeps every stroke", "feasible range"} <= set(said)


def test_the_reachable_area_is_the_free_one_less_what_passes_a_stroke(crane):
    """The same seeded configurations: with every stroke checked, the points are those of the
    unchecked sample whose actuator values keep their strokes, and the crane's strokes drop some."""
    from redundancy.resolution.state import evaluate
    from redundancy.study.check import REACH_SAMPLES, reachable_points

    free = reachable_points(crane, ())
    kept = reachable_points(crane, tuple(crane.actuators.names))
    assert len(free) == REACH_SAMPLES and 0 < len(kept) < len(free)
    lower = np.where(np.isfinite(crane.lower), crane.lower, -np.pi)
    upper = np.where(np.isfinite(crane.upper), crane.upper, np.pi)
    q = np.random.default_rng(0).uniform(lower, upper, (REACH_SAMPLES, crane.n))
    x = evaluate(crane, q).x
    inside = ((x >= crane.actuators.lower) & (x <= crane.actuators.upper)).all(axis=1)
    assert np.array_equal(kept, free[inside])


def test_a_gauge_names_every_limit_a_cylinder_is_at_or_past():
    """The M_H-weighted law from the default start of 1-2 drives the telescope faster than its
    cylinder's maximum speed, then past its stroke: at each shown sample each actuator's gauge
    says "at its stroke limit" within 1 mm of a stroke end, "past its stroke limit" beyond it,
    and "past its speed limit" and "past its pressure limit" past the cylinder's speed and the
    load pressure the supply serves, each that holds. A gauge used to say "at its stroke limit"
    a metre past it, and only the speed where both were passed."""
    from redundancy import ENERGY
    from redundancy.planning.starts import default_start

    robot = load_robot("hiab031", payload=100.0)
    segment = WorkCycle.from_toml(robot.task_file, dimension=robot.m)["1-2"]
    _, q = default_start(robot, segment)
    motion = simulate(robot, ENERGY.resolver, segment, q[None])
    playback = Playback(motion)
    shown = playback.samples
    circuit = robot.circuit()
    x, x_dot = motion.x[0, shown], motion.x_dot[0, shown]
    lower, upper = robot.actuators.lower, robot.actuators.upper
    past = np.maximum(lower - x, x - upper) > 1e-3
    at = np.minimum(x - lower, upper - x) <= 1e-3
    speed = np.zeros_like(past)
    pressure = np.zeros_like(past)
    speed[:, circuit.columns] = np.abs(x_dot[:, circuit.columns]) > circuit.max_speeds
    pressure[:, circuit.columns] = motion.flows.load[0, shown] > circuit.supply.available(
        circuit.relief
    )
    expected = [
        [
            "; ".join(
                word
                for word, holds in (
                    ("past its stroke limit", p),
                    ("at its stroke limit", a and not p),
                    ("past its speed limit", v),
                    ("past its pressure limit", f),
                )
                if holds
            )
            for p, a, v, f in zip(*row)
        ]
        for row in zip(past, at, speed, pressure)
    ]
    assert past.any() and speed.any()
    assert playback.alarms().tolist() == expected


def test_a_mirrored_mesh_is_posed_as_the_scene_decomposes_it():
    """A mirrored mesh (<mesh scale="-1 1 1">, a left part drawn from a right one) has a
    placement whose block R diag(s) has det < 0, which has no nearest rotation: its playback
    ended in an internal error after the whole study. three.js takes such a matrix's scale
    along x as negative, so its rotation is R diag(−1, 1, 1) diag(s) / |s|: R itself for a
    mirror in x, R diag(−1, −1, 1) for one in y."""
    from scipy.spatial.transform import Rotation

    from redundancy.viz.playback import quaternions

    R = Rotation.from_euler("xyz", [0.3, -0.7, 1.1]).as_matrix()
    for scale, rotation in (((-1, 1, 1), R), ((1, -2, 1), R @ np.diag([-1.0, -1.0, 1.0]))):
        T = np.eye(4)
        T[:3, :3] = R @ np.diag(scale)
        expected = Rotation.from_matrix(rotation).as_quat(canonical=True)
        np.testing.assert_allclose(quaternions(T[None])[0], expected, atol=1e-12)


def test_with_four_held_actuators_the_star_is_at_the_first_two_values(request):
    """The Panda holds four joints; Fig. 4a draws over the first two, and the best start's
    star sits at its values of those two (matplotlib read four values as two points)."""
    from redundancy import improved_start
    from redundancy.viz.plots import peak_map_figure, pyplot

    with pytest.warns(UserWarning):  # the Panda's joints are driven directly
        arm = load_robot("panda")
    cycle = WorkCycle.from_toml(arm.task_file, dimension=arm.m)
    search = improved_start(arm, cycle.segments[0], VELOCITY, held=cycle.held, samples=6)
    figure = peak_map_figure((search,), "peak")
    request.addfinalizer(lambda: pyplot().close(figure))
    (star,) = [line for line in figure.axes[0].lines if line.get_marker() == "*"]
    np.testing.assert_array_equal(star.get_xydata(), [search.best.values[:2]])
