"""Playback of a motion in meshcat: live in a browser, or as one self-contained HTML page.

Drawn: every link of the URDF, locked links included (Pinocchio's meshcat visualizer; a link
without visual geometry, or whose meshes no file answers, as the convex hull of its origin, its
joints and the actuators' points on it); every `LinearCylinder` and `LinkageCylinder` as a
barrel and a rod, red at or past a stroke limit; each linkage's rocker and coupler; the desired
and the traced paths, the task points, and a grid behind the machine. The camera looks at the
task plane (the crane's world x–z, from −y) and frames the whole motion.

The motion is one `meshcat.animation.Animation` looping in the browser. `export_html` records
meshcat's commands into a page that embeds its viewer script and needs no network; `play`
serves the same page from a meshcat server on localhost until interrupted. Over the scene the
page shows the title, the time, play and pause, a time slider, the grid's spacing and each
actuator's value and speed with a gauge of its stroke, red at a limit (a stroke's end, or a
cylinder's speed or load pressure past what the circuit allows). ``?t=SECONDS`` opens the page
at that instant, paused.
"""

from __future__ import annotations

import base64
import contextlib
import copy
import html
import io
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator
from itertools import product
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from redundancy.errors import InvalidInputError, RedundancyError, RobotDescriptionError
from redundancy.model.actuators import LinearCylinder
from redundancy.model.kinematics import Kinematics
from redundancy.model.linkage import LinkageCylinder
from redundancy.model.robot import AXES, frame_id
from redundancy.planning.integrate import Trajectory
from redundancy.planning.tasks import WorkCycle
from redundancy.study.cycles import CycleStudy
from redundancy.study.output import write_atomically
from redundancy.study.study import Study
from redundancy.viz.server import LOCALHOST

STARTUP = 30.0  # s: the meshcat server must have said where it listens by then
FRAME_RATE = 30.0  # frames per second of playback; the motion is sampled at most this often
FIELD_OF_VIEW = 30.0  # degrees, vertical
ASPECT = 4 / 3  # width / height the camera distance is fitted for
MARGIN = 1.45  # the camera's distance, in units of the distance that just fits the scene: room
# for the page's title and gauges above and its controls below
LIFT = 0.12  # the camera aims this share of the view's half-height above the scene's centre, so
# that the scene sits lower, clear of the title and gauges, which take more room than controls
LIMIT_MARGIN = 1e-3  # m: a cylinder this close to a stroke limit counts as at it
ROOT = "playback"  # every drawn object hangs below this node
PARTS = ("barrel", "rod")

COLOURS = {
    "barrel": 0x46505A,
    "rod": 0xD2D2D2,
    "bar": 0x8C8C8C,
    "limit": 0xD62728,
    "desired": 0x2CA02C,
    "traced": 0x1F4FB4,
    "points": 0x202020,
    "grid": 0xB4BAC4,
    "hull": 0xE8A33D,
}
BACKGROUND = [0.93, 0.94, 0.96]  # RGB, 0-1: light, yet light links stand out

# Camera direction (from the scene towards the camera) for each planar task, so the task axes
# appear left to right and bottom to top; other tasks get a view raised by ELEVATION that faces
# the tool's path (`Playback.view`).
VIEWS = {"xz": (0.0, -1.0, 0.0), "yz": (1.0, 0.0, 0.0), "xy": (0.0, -0.3, 1.0)}
ELEVATION = 1.0  # the camera's rise over its horizontal distance for a task in space (45°)
ASIDE = np.radians(-35.0)  # and its turn about the vertical away from facing the path square on
UPRIGHT = 0.1  # a path whose horizontal spread is below this share of its vertical one is upright


def _meshcat():
    """meshcat, imported when first drawn."""
    import meshcat
    import meshcat.animation
    import meshcat.geometry
    import meshcat.transformations

    return meshcat


def _rgb(colour: int) -> list[float]:
    """A 0xRRGGBB colour as [r, g, b] in 0-1."""
    return [((colour >> shift) & 0xFF) / 255 for shift in (16, 8, 0)]


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Transforms (k, 4, 4) that place a meshcat cylinder (its axis is its local y) with its ends
    at a and b, each (k, 3) in m; the cylinder's height must be |b − a|."""
    d = b - a
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    least = np.eye(3)[np.argmin(np.abs(u), axis=1)]  # the world axis farthest from u
    side = np.cross(u, least)
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    T = np.zeros((len(a), 4, 4))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = side, u, np.cross(side, u)
    T[:, :3, 3] = (a + b) / 2
    T[:, 3, 3] = 1.0
    return T


def quaternions(transforms: np.ndarray) -> np.ndarray:
    """The rotations of transforms (k, 4, 4) as quaternions (k, 4), [x, y, z, w] with w ≥ 0, as
    meshcat's `quaternion_from_matrix` gives them one matrix at a time: scipy's takes the same
    method (Bar-Itzhack's), the quaternion of the rotation nearest the upper-left block even
    where it is not orthonormal (a scaled mesh's transform). A mirrored mesh's block (a scale
    with one negative entry, det < 0) has no rotation near it: as the scene's three.js takes its
    scale along x as negative there, the rotation is that of the block with its first column
    turned."""
    from scipy.spatial.transform import Rotation

    blocks = transforms[:, :3, :3].copy()
    blocks[np.linalg.det(blocks) < 0, :, 0] *= -1
    return Rotation.from_matrix(blocks).as_quat(canonical=True)


def task_points(cycle: WorkCycle) -> np.ndarray:
    """The distinct ends of a work cycle's segments, (P, m) in m."""
    ends = [p for s in cycle.segments for p in (s.start, s.end)]
    return np.unique(np.array(ends), axis=0)


class Cylinder(NamedTuple):
    """How one `LinearCylinder` or `LinkageCylinder` is drawn: a barrel of length ``part`` (m)
    from the base point and a rod as long ending at the rod point, spanning the actuator value
    x_i (Eq. 9); ``part`` is the closed length, so the rod stays inside the barrel."""

    name: str
    actuator: LinearCylinder | LinkageCylinder
    part: float


def at_stroke_limit(x: np.ndarray, lower, upper) -> np.ndarray:
    """Whether each actuator value x (..., n) (or (k,) of one actuator) is within `LIMIT_MARGIN`
    (m or rad) of its stroke's ``lower`` or ``upper`` end (n,), or past it."""
    return np.minimum(x - lower, upper - x) <= LIMIT_MARGIN


def _visual_model(robot) -> tuple[Any, tuple[str, ...]]:
    """Pinocchio's model of the URDF's visual geometry (None where there is none), and the mesh
    files it leaves out, whose links are drawn as hulls: those no file answers
    (`Robot.missing_meshes`) and those the mesh loader cannot read, named in a warning (found
    one by one where the whole fails)."""
    import pinocchio as pin
    from lxml import etree

    from redundancy.model.urdf import pinocchio_message

    description = etree.fromstring(robot.description.encode())
    meshes = {m.get("filename", "") for m in description.findall("link/visual/geometry/mesh")}

    def built(left_out: set[str]):
        kept = copy.deepcopy(description)
        for visual in kept.findall("link/visual"):
            mesh = visual.find("geometry/mesh")
            if mesh is not None and mesh.get("filename", "") in left_out:
                visual.getparent().remove(visual)
        if kept.find("link/visual") is None:
            return None
        text = etree.tostring(kept, encoding="unicode")  # every mesh named by its absolute path
        return pin.buildGeomFromUrdfString(robot.model, text, pin.GeometryType.VISUAL)

    missing = set(robot.missing_meshes)
    try:
        return built(missing), tuple(sorted(missing))
    except (ValueError, RuntimeError) as error:
        failure = error

    def loads(mesh: str) -> bool:  # with that mesh alone
        try:
            built(meshes - {mesh})
        except (ValueError, RuntimeError):
            return False
        return True

    unreadable = [mesh for mesh in sorted(meshes - missing) if not loads(mesh)]
    try:
        if not unreadable:  # no mesh is to blame
            raise failure
        visuals = built(missing | set(unreadable))
    except (ValueError, RuntimeError):
        raise RobotDescriptionError(
            f"{robot.urdf}: cannot load its visual geometry: {pinocchio_message(failure)}"
        ) from failure
    warnings.warn(
        f"{robot.urdf}: meshes that cannot be read, the playback draws those links as hulls: "
        f"{', '.join(unreadable)}",
        stacklevel=3,
    )
    return visuals, tuple(sorted(missing | set(unreadable)))


def link_points(robot, undrawn: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The points fixed on each link without a drawn visual (a shape, or a mesh not among
    ``undrawn``), (P, 3) in m in the link's own frame: its origin, the origins of the joints it
    carries and the actuators' points on it (a cylinder's base and rod, a linkage's pins),
    locked links included. A link is drawn as their convex hull, so that the cylinders sit on
    it."""
    import yourdfpy

    from redundancy.model.parameters import Point

    # the robot's URDF text: a xacro expanded, the meshes found by absolute path
    text = io.BytesIO(robot.description.encode())
    parse = yourdfpy.URDF.load(text, build_scene_graph=False, load_meshes=False).robot
    points = {  # the links none of whose visuals is a shape or a mesh drawn (not ``undrawn``)
        link.name: [np.zeros(3)]
        for link in parse.links
        if all(
            v.geometry.mesh is not None and v.geometry.mesh.filename in undrawn
            for v in link.visuals
        )
    }
    for joint in parse.joints:
        if joint.parent in points and joint.origin is not None:
            points[joint.parent].append(np.asarray(joint.origin)[:3, 3])
    for actuator in robot.actuators:
        for parameter in actuator.parameters:
            if isinstance(parameter, Point):
                link, xyz = getattr(actuator, parameter.name)[:2]
                if link in points:
                    points[link].append(np.asarray(xyz, dtype=float))
    return {link: np.unique(found, axis=0) for link, found in points.items() if len(found) > 1}


def brackets(robot, visuals) -> dict[str, tuple[int, np.ndarray]]:
    """For each cylinder pin (a base or a rod end, a linkage's pins) on a link drawn by its
    visual geometry that lies off it, a bracket: the pin and the nearest point of the nearest
    of the visuals its joint carries (each a box, its local bounding box placed as drawn), by
    node name: (the joint, the two points (2, 3) in m in the joint's frame). Without
    one, a pin the mesh does not reach (the crane's fold cylinder below its boom) floats."""
    from redundancy.model.parameters import Point

    if visuals is None:
        return {}
    model, found = robot.model, {}
    boxes = []  # (joint, placement, lower, upper) of each visual
    for item in visuals.geometryObjects:
        item.geometry.computeLocalAABB()
        box = item.geometry.aabb_local  # a mesh's, as loaded: its scale is in it already
        boxes.append((item.parentJoint, item.placement, np.asarray(box.min_), np.asarray(box.max_)))
    for actuator in robot.actuators:
        for parameter in actuator.parameters:
            if not isinstance(parameter, Point):
                continue
            link, xyz = getattr(actuator, parameter.name)[:2]
            if not model.existFrame(link):
                continue
            frame = model.frames[model.getFrameId(link)]
            pin = frame.placement.act(np.asarray(xyz, dtype=float))  # in its joint's frame
            nearest, gap = None, np.inf
            for joint, placement, lower, upper in boxes:
                if joint != frame.parentJoint:
                    continue
                local = placement.actInv(pin)
                foot = placement.act(np.clip(local, lower, upper))
                if np.linalg.norm(pin - foot) < gap:
                    nearest, gap = foot, float(np.linalg.norm(pin - foot))
            if nearest is not None and gap > 1e-3:  # m: a pin on its mesh needs none
                found[f"{actuator.name}_{parameter.name}"] = (
                    frame.parentJoint,
                    np.array([pin, nearest]),
                )
    return found


def hull(points: np.ndarray, thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull of ``points`` (P, 3), each grown into a cube of side ``thickness`` (m) so
    that points on a line or in a plane still enclose a body: vertices (V, 3) and triangles
    (F, 3) of vertex indices."""
    from scipy.spatial import ConvexHull

    corners = np.array(list(product((-0.5, 0.5), repeat=3)))
    grown = (points[:, None, :] + thickness * corners).reshape(-1, 3)
    found = ConvexHull(grown)
    used = np.unique(found.simplices)
    return grown[used], np.searchsorted(used, found.simplices)


class Playback:
    """The drawing of one motion (a `Trajectory` of one) and its poses over time.

    ``points`` (P, m) are task points to mark, in task coordinates (default: the segment's
    ends). ``samples`` are the indices of the motion's times that playback shows, at most
    `FRAME_RATE` per second and always the last. ``centre`` (3,) is the middle of the scene's
    box, ``aim`` (3,) the world point shown at the middle of the view (above the centre: `LIFT`)
    and ``distance`` (m) the camera's distance from it, fitted so that every link's visual
    geometry (or every frame), the paths and the points are in view over the whole motion;
    ``size`` (m) is the scene's largest extent, which sizes the markers and the grid.
    """

    def __init__(self, motion: Trajectory, points: np.ndarray | None = None) -> None:
        if len(motion) != 1:
            raise InvalidInputError(f"a playback shows one motion; got {len(motion)}")
        self.motion = motion
        self.robot = robot = motion.robot
        self.visuals, undrawn = _visual_model(robot)
        segment = motion.segment
        self.q = motion.q[0]
        self.t = motion.t[0]
        step = math.ceil(1 / (FRAME_RATE * (self.t[1] - self.t[0])) - 1e-9)
        self.samples = np.unique(np.append(np.arange(0, len(self.t), step), len(self.t) - 1))
        kinematics = motion.space.kinematics  # the motion's own, as the integrator evaluated it
        self.traced = robot.tool(kinematics).position
        rows = [AXES.index(a) for a in robot.task_axes]

        def world(y: np.ndarray) -> np.ndarray:
            """Task points (P, m) as world points (P, 3), off-plane components from the start;
            a tool angle (a task coordinate past the position's) is not drawn."""
            p = np.repeat(self.traced[:1], len(y), axis=0)
            p[:, rows] = y[:, : len(rows)]
            return p

        outline = getattr(segment, "outline", None)
        path = outline() if outline is not None else np.array([segment.start, segment.end])
        self.desired = world(np.asarray(path, dtype=float))
        marked = np.array([segment.start, segment.end]) if points is None else points
        self.points = world(np.atleast_2d(np.asarray(marked, dtype=float)))
        self.cylinders = []
        for actuator in robot.actuators:
            if isinstance(actuator, LinearCylinder | LinkageCylinder):
                base, rod = actuator.ends(kinematics)
                shortest = float(np.linalg.norm(rod - base, axis=1).min())
                closed = actuator.lower if 0 < actuator.lower < np.inf else shortest
                self.cylinders.append(Cylinder(actuator.name, actuator, min(closed, shortest)))
        # Each linkage's rocker and coupler: (actuator, bar name, length in m).
        self.bars = [
            (actuator, bar, float(np.linalg.norm(b[0] - a[0])))
            for actuator in robot.actuators
            if isinstance(actuator, LinkageCylinder)
            for bar, (a, b) in actuator.bars(kinematics).items()
        ]
        self.hulls = link_points(robot, undrawn)  # the links without a drawn visual, as hulls
        self.frames = {link: frame_id(robot.model, link) for link in self.hulls}
        self.brackets = brackets(robot, self.visuals)  # pins off their links' meshes
        self._poses, extent = self._link_poses(self.q[self.samples])  # the links' at the samples
        self._fit_camera(np.concatenate([extent, self.traced, self.points]))

    def _link_poses(self, q: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The links' poses at the configurations ``q`` (k, n), from one Pinocchio pass each (the
        compiled pass tracks points, not orientations): each hull's link frame and each visual's
        placement, scaled as Pinocchio's visualizer scales its mesh, (k, 4, 4) by node path
        below the scene's root; and the points the view must hold, (P, 3) in m: every frame's
        origin and the corners of each visual's bounding box."""
        import pinocchio as pin

        model, data = self.robot.model, self.robot.data
        items = [] if self.visuals is None else self.visuals.geometryObjects
        geometry = None if self.visuals is None else self.visuals.createData()
        boxes = []
        for item in items:
            item.geometry.computeLocalAABB()
            box = item.geometry.aabb_local
            boxes.append(np.array(list(product(*zip(box.min_, box.max_)))))
        poses: dict[str, list[np.ndarray]] = {}
        found = []
        for row in q:
            pin.framesForwardKinematics(model, data, row)
            found.append(np.array([frame.translation for frame in data.oMf]))
            for link, frame in self.frames.items():
                poses.setdefault(f"links/hulls/{link}", []).append(data.oMf[frame].homogeneous)
            for name, (joint, _) in self.brackets.items():
                poses.setdefault(f"links/brackets/{name}", []).append(data.oMi[joint].homogeneous)
            if geometry is not None:
                pin.updateGeometryPlacements(model, data, self.visuals, geometry)
                for item, corners, placed in zip(items, boxes, geometry.oMg):
                    found.append(corners @ placed.rotation.T + placed.translation)
                    scaled = placed.homogeneous @ np.diag([*item.meshScale, 1.0])
                    poses.setdefault(f"links/visuals/{item.name}", []).append(scaled)
        return {path: np.array(kept) for path, kept in poses.items()}, np.concatenate(found)

    def _view(self) -> np.ndarray:
        """The direction from the scene towards the camera: facing a planar task's plane
        (`VIEWS`); for a task in space, raised by `ELEVATION` over the horizontal direction
        along which the tool's path (desired and traced) spreads least, from the side of the
        path away from the machine's base (the world's origin), turned `ASIDE` about the
        vertical: the path is seen nearly broadside (a slew's swing over a quarter turn was seen
        edge-on) and a boom that points along the view at the swing's middle is seen from the
        side all the same. A path that spreads little horizontally (`UPRIGHT`: a lift) is seen
        across the vertical plane through the base and the path, where the boom moves."""
        axes = "".join(sorted(self.robot.task_axes))
        if axes in VIEWS:
            return np.array(VIEWS[axes])
        path = np.concatenate([self.desired, self.traced])
        centre = path.mean(axis=0)
        spread, directions = np.linalg.eigh(np.cov((path - centre)[:, :2].T) + 1e-30 * np.eye(2))
        height = np.std(path[:, 2])  # the vertical spread, as the horizontal one is measured
        if np.sqrt(spread[-1]) < UPRIGHT * height or np.sqrt(spread[-1]) < 1e-9:
            outward = centre[:2] if np.linalg.norm(centre[:2]) > 1e-9 else np.array([1.0, 0.0])
            horizontal = np.array([outward[1], -outward[0]])  # across that plane
        else:
            horizontal = directions[:, 0]  # the path's least horizontal spread
            if horizontal @ centre[:2] < 0:
                horizontal = -horizontal
            turn = np.array([[np.cos(ASIDE), -np.sin(ASIDE)], [np.sin(ASIDE), np.cos(ASIDE)]])
            horizontal = turn @ horizontal
        horizontal /= np.linalg.norm(horizontal)
        return np.array([*horizontal, ELEVATION])

    def _fit_camera(self, points: np.ndarray) -> None:
        self.view = self._view()
        self.view /= np.linalg.norm(self.view)
        low, high = points.min(axis=0), points.max(axis=0)
        self.centre = (low + high) / 2
        self.size = float(np.max(high - low))
        right = np.cross([0.0, 0.0, 1.0], self.view)
        right /= np.linalg.norm(right)
        up = np.cross(self.view, right)
        offsets = points - self.centre
        half_width = np.max(np.abs(offsets @ right))
        half_height = np.max(np.abs(offsets @ up))
        fit = max(half_height, half_width / ASPECT) / math.tan(math.radians(FIELD_OF_VIEW) / 2)
        self.distance = float(np.max(offsets @ self.view) + MARGIN * fit)
        self.depth = float(np.max(-offsets @ self.view))  # how far the scene reaches behind
        reach = self.distance * math.tan(math.radians(FIELD_OF_VIEW) / 2)  # at the centre
        self.aim = self.centre + LIFT * reach * up

    def draw(self, vis) -> None:
        """Put the scene into the meshcat visualizer ``vis`` and show the motion's first pose."""
        meshcat = _meshcat()
        mg = meshcat.geometry

        for node in ("/Grid", "/Axes"):
            vis[node].set_property("visible", False)
        vis["/Background"].set_property("top_color", BACKGROUND)
        vis["/Background"].set_property("bottom_color", BACKGROUND)
        camera = vis["/Cameras/default/rotated/<object>"]
        camera.set_property("fov", FIELD_OF_VIEW)
        x, y, z = self.distance * self.view
        camera.set_property("position", [x, z, -y])  # the camera's frame has y up
        # The camera orbits the world origin, so the scene is moved to put its aim there.
        root = vis[ROOT]
        root.set_transform(meshcat.transformations.translation_matrix(-self.aim))

        # the links: the hulls, ``size`` / 50 thick (m), and the visual geometry as
        # Pinocchio's visualizer loads it; both posed by `placements`
        material = mg.MeshLambertMaterial(color=COLOURS["hull"])
        for name, (_, points) in self.brackets.items():
            vertices, faces = hull(points, self.size / 80)
            geometry = mg.TriangularMeshGeometry(vertices, faces)
            root[f"links/brackets/{name}"].set_object(
                geometry, mg.MeshLambertMaterial(color=COLOURS["bar"])
            )
        for link, points in self.hulls.items():
            vertices, faces = hull(points, self.size / 50)
            mesh = mg.TriangularMeshGeometry(vertices, faces)
            root[f"links/hulls/{link}"].set_object(mesh, material)
        if self.visuals is not None:
            from pinocchio.visualize import MeshcatVisualizer

            links = MeshcatVisualizer(self.robot.model, None, self.visuals)
            links.initViewer(viewer=root)
            links.loadViewerModel(rootNodeName="links")

        for cylinder in self.cylinders:
            for part, radius in zip(PARTS, (0.06, 0.035)):
                material = mg.MeshLambertMaterial(color=COLOURS[part])
                geometry = mg.Cylinder(cylinder.part, radius * cylinder.part)
                root[f"cylinders/{cylinder.name}/{part}"].set_object(geometry, material)
        for actuator, bar, length in self.bars:
            material = mg.MeshLambertMaterial(color=COLOURS["bar"])
            geometry = mg.Cylinder(length, 0.08 * length)
            root[f"linkages/{actuator.name}/{bar}"].set_object(geometry, material)

        size = self.size
        # A translucent band for the desired path (a straight piece per stretch of it), the
        # traced path as dots along its middle.
        material = mg.MeshLambertMaterial(color=COLOURS["desired"], opacity=0.35)
        pieces = [(a, b) for a, b in zip(self.desired[:-1], self.desired[1:]) if np.any(a != b)]
        for i, (start, end) in enumerate(pieces):
            node = root["desired"] if len(pieces) == 1 else root[f"desired/{i}"]
            node.set_object(mg.Cylinder(float(np.linalg.norm(end - start)), 0.008 * size), material)
            node.set_transform(_between(start[None], end[None])[0])
        colours = np.outer(_rgb(COLOURS["traced"]), np.ones(len(self.traced)))
        # meshcat's points take their colour from per-vertex colours only; the traced path lies
        # in front of the band, towards the camera, so that the band never hides it
        traced = self.traced + 0.02 * size * self.view
        dots = mg.PointsGeometry(traced.T.astype(np.float32), colours.astype(np.float32))
        root["traced"].set_object(dots, mg.PointsMaterial(size=0.015 * size))
        lines = mg.PointsGeometry(self.grid().T.astype(np.float32))
        root["grid"].set_object(mg.LineSegments(lines, mg.LineBasicMaterial(color=COLOURS["grid"])))
        for i, point in enumerate(self.points):
            node = root[f"points/{i}"]
            node.set_object(
                mg.Sphere(0.012 * size), mg.MeshLambertMaterial(color=COLOURS["points"])
            )
            node.set_transform(meshcat.transformations.translation_matrix(point))
        # the first pose; the animation colours a cylinder red at a stroke limit
        first = {path: poses[:1] for path, poses in self._poses.items()}
        placed, _ = self._placed(first, self.motion.space.kinematics.take(np.zeros(1, dtype=int)))
        for path, poses in placed.items():
            root[path].set_transform(poses[0])

    @property
    def spacing(self) -> float:
        """The grid's spacing (m): 1, 2 or 5 times a power of ten, some 10-25 lines across."""
        step = self.size / 10
        decade = 10 ** math.floor(math.log10(step))
        return decade * min((1, 2, 5, 10), key=lambda m: abs(math.log(step / (m * decade))))

    def grid(self) -> np.ndarray:
        """The grid's lines as pairs of end points (2L, 3), m: just behind the scene in the
        plane facing the camera for a planar task, else on the ground below it; lines fall on
        multiples of `spacing`, so that its squares read as a scale."""
        planar = np.count_nonzero(self.view) == 1
        normal = self.view if planar else np.array([0.0, 0.0, 1.0])
        a, b = (np.eye(3)[i] for i in np.flatnonzero(normal == 0)[:2])
        half = 0.75 * self.size
        reach = self.depth if planar else self.size / 2
        level = self.centre @ normal - reach - 0.05 * self.size
        pieces = []
        for along, across in ((a, b), (b, a)):
            low = math.floor((self.centre @ along - half) / self.spacing)
            high = math.ceil((self.centre @ along + half) / self.spacing)
            for k in range(low, high + 1):
                base = k * self.spacing * along + level * normal
                middle = (self.centre @ across) * across
                pieces += [base + middle - half * across, base + middle + half * across]
        return np.array(pieces)

    def placements(self, q: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The poses of the drawn links, linkage bars and cylinders at the configurations
        ``q`` (k, n): their transforms (k, 4, 4) by node path below the scene's root, in the
        order the scene first poses them, and which cylinders are at or past a stroke limit,
        (k, C) bool. One kinematics pass serves the whole batch."""
        return self._placed(self._link_poses(q)[0], self.robot.kinematics(q))

    def _placed(self, links: dict, kinematics: Kinematics) -> tuple[dict, np.ndarray]:
        """`placements`, from the links' poses ``links`` (`_link_poses`) and the tracked
        frames' ``kinematics`` at the same configurations."""
        placed = dict(links)
        for actuator, bar, _ in self.bars:
            a, b = actuator.bars(kinematics)[bar]
            placed[f"linkages/{actuator.name}/{bar}"] = _between(a, b)
        limited = np.empty((len(kinematics.q), len(self.cylinders)), dtype=bool)
        for column, cylinder in enumerate(self.cylinders):
            base, rod = cylinder.actuator.ends(kinematics)
            length = np.linalg.norm(rod - base, axis=1)
            u = (rod - base) / length[:, None]
            barrel = _between(base, base + cylinder.part * u)
            placed[f"cylinders/{cylinder.name}/barrel"] = barrel
            placed[f"cylinders/{cylinder.name}/rod"] = _between(rod - cylinder.part * u, rod)
            stroke = cylinder.actuator
            limited[:, column] = at_stroke_limit(length, stroke.lower, stroke.upper)
        return placed, limited

    def alarms(self) -> np.ndarray:
        """Which limits each actuator is at or past at each shown sample, (S, n) text: "at its
        stroke limit" within `LIMIT_MARGIN` of a stroke's end, "past its stroke limit" beyond it;
        with a hydraulic circuit and masses also "past its speed limit" or "past its pressure
        limit" past the cylinder's maximum speed or the load pressure the supply serves (the
        motion's own `hydraulic_values`), each that holds, joined by "; "; else ""."""
        motion, robot = self.motion, self.robot
        actuators = robot.actuators
        x = motion.x[0, self.samples]
        beyond = np.maximum(actuators.lower - x, x - actuators.upper) > LIMIT_MARGIN
        at = at_stroke_limit(x, actuators.lower, actuators.upper)
        stroke = np.where(beyond, "past its stroke limit", np.where(at, "at its stroke limit", ""))
        found = [[[word] if word else [] for word in row] for row in stroke.tolist()]
        if robot.hydraulics is not None and not robot.kinematic_only:
            circuit = robot.circuit()
            c = len(circuit.names)
            past = motion.hydraulic_limits.excess(motion.hydraulic_values[0, self.samples]) > 0
            for kind, columns in (("speed", slice(c + 1, 2 * c + 1)), ("pressure", slice(0, c))):
                for row, cylinder in zip(*np.nonzero(past[:, columns])):
                    found[row][circuit.columns[cylinder]].append(f"past its {kind} limit")
        return np.array([["; ".join(words) for words in row] for row in found], dtype=object)

    def overlay(self, title: str) -> dict:
        """What the page shows over the scene, JSON-ready: its ``title``, the grid's spacing (m),
        the shown samples' times (S,) s, each actuator's name, unit, stroke ends (None where
        unbounded), values and speeds (S, n) and `alarms`, and the legend of the scene's
        colours, (colour, what) pairs."""
        actuators = self.robot.actuators
        finite = [
            float(v) if np.isfinite(v) else None for v in (*actuators.lower, *actuators.upper)
        ]
        n = len(actuators.names)
        return {
            "title": title,
            "grid": self.spacing,
            "t": np.round(self.t[self.samples], 4).tolist(),
            "names": list(actuators.names),
            "units": [a.unit for a in actuators],
            "lower": finite[:n],
            "upper": finite[n:],
            "x": np.round(self.motion.x[0, self.samples], 5).tolist(),
            "x_dot": np.round(self.motion.x_dot[0, self.samples], 5).tolist(),
            "alarm": self.alarms().tolist(),
            "legend": [
                (f"#{COLOURS[key]:06x}", what)
                for key, what in (
                    ("desired", "the task's path"),
                    ("traced", "the tool's path"),
                    ("points", "task points"),
                    ("limit", "an actuator at or past a limit"),
                )
            ],
        }

    def animation(self, vis):
        """The motion as a `meshcat.animation.Animation` for ``vis``, keyed at every shown
        sample's time t (s), frame t·`FRAME_RATE`: each drawn node's position and quaternion,
        and each cylinder part's colour."""
        animation = _meshcat().animation
        frames = (self.t[self.samples] * FRAME_RATE).tolist()
        placed, limited = self._placed(self._poses, self.motion.space.kinematics.take(self.samples))
        root = vis[ROOT]

        def clip(path: str, *tracks: tuple[str, str, list]) -> tuple[Any, Any]:
            """The node ``path``'s clip of tracks (property, type, values at the frames)."""
            keyed = {
                name: animation.AnimationTrack(name, kind, frames, v) for name, kind, v in tracks
            }
            return root[path].path, animation.AnimationClip(keyed, fps=FRAME_RATE)

        clips = [
            clip(
                path,
                ("position", "vector3", poses[:, :3, 3].tolist()),
                ("quaternion", "quaternion", quaternions(poses).tolist()),
            )
            for path, poses in placed.items()
        ]
        for column, cylinder in enumerate(self.cylinders):
            for part in PARTS:
                red = limited[:, column, None]
                colours = np.where(red, _rgb(COLOURS["limit"]), _rgb(COLOURS[part])).tolist()
                path = f"cylinders/{cylinder.name}/{part}/<object>"
                clips.append(clip(path, ("material.color", "color", colours)))
        return animation.Animation(dict(clips), default_framerate=FRAME_RATE)


class Recording:
    """A stand-in for meshcat's viewer window that keeps every command instead of sending it
    to a server; ``get_scene`` (behind `meshcat.Visualizer.static_html`) writes them into a
    self-contained page, with the ``overlay`` (`Playback.overlay`) drawn over the scene where
    one is given. ``commands`` holds each command msgpack-encoded, in order: the bytes
    meshcat's own encoder (umsgpack, pure Python) gives, by msgpack's compiled one."""

    def __init__(self, title: str = "redundancy playback", overlay: dict | None = None) -> None:
        self.title = title
        self.overlay = overlay
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        import msgpack

        self.commands.append(msgpack.packb(command.lower(), default=_extension))

    def get_scene(self) -> str:
        viewer = Path(_meshcat().__file__).parent / "viewer" / "dist" / "main.min.js"
        commands = ",\n".join(f'"{base64.b64encode(c).decode()}"' for c in self.commands)
        # Decoded in order and synchronously (meshcat's own page fetches each one
        # asynchronously), so that the scene and animation exist when the time is chosen.
        scene = (
            f"for (const command of [\n{commands}\n]) {{\n  viewer.handle_command_bytearray("
            "Uint8Array.from(atob(command), c => c.charCodeAt(0)));\n}"
        )
        return _html(self.title, self.overlay, f"<script>{viewer.read_text()}</script>", scene)


def _html(title: str, overlay: dict | None, viewer: str, scene: str) -> str:
    """A playback page (playback.html): its ``title``, meshcat's ``viewer`` script element, the
    ``scene`` script that fills the viewer, and what it shows over the scene (overlay.html, from
    `Playback.overlay`) where ``overlay`` is given. Each @-marker is filled in one pass, so that
    none is looked for inside what fills another."""
    here = Path(__file__).parent

    def filled(name: str, values: dict[str, str]) -> str:
        text = (here / name).read_text(encoding="utf-8")
        return re.sub(r"@([A-Z]+)@", lambda marker: values[marker.group(1)], text)

    shown = "" if overlay is None else filled("overlay.html", {"DATA": json.dumps(overlay)})
    markers = {"TITLE": html.escape(title), "VIEWER": viewer, "SCENE": scene, "OVERLAY": shown}
    return filled("playback.html", markers)


def _extension(value):
    """meshcat's typed arrays (umsgpack extension values) as msgpack's extension values."""
    import msgpack
    import umsgpack

    if isinstance(value, umsgpack.Ext):
        return msgpack.ExtType(value.type, value.data)
    raise TypeError(f"cannot encode {type(value).__name__} for meshcat")


def _titles(motion: Trajectory, strategy: str | None) -> tuple[str, str]:
    """A playback page's title (robot and segment or cycle) and its heading, which adds how the
    motion was made: ``strategy``, by default its resolver's name."""
    segment = motion.segment
    what = "cycle" if hasattr(segment, "segments") else "segment"
    title = f"{motion.robot.name}: {what} {segment.name}"
    return title, f"{title}, {strategy or motion.resolver.name}"


def _shown(playback: Playback, vis) -> None:
    """Draw ``playback`` into ``vis``, its animation looping."""
    playback.draw(vis)
    vis.set_animation(playback.animation(vis), play=True, repetitions=math.inf)


def export_html(
    motion: Trajectory,
    path: Path | str,
    points: np.ndarray | None = None,
    strategy: str | None = None,
) -> Path:
    """Write a self-contained HTML page that plays ``motion`` in a loop, with no server and no
    network, to ``path`` (atomically); return the path. ``points`` as in `Playback`;
    ``strategy`` names how the motion was made, for the title (default: its resolver's name)."""
    title, heading = _titles(motion, strategy)
    playback = Playback(motion, points)
    vis = _meshcat().Visualizer(window=Recording(title, playback.overlay(heading)))
    _shown(playback, vis)
    text = vis.static_html()
    path = Path(path)
    write_atomically(path, lambda p: p.write_text(text, encoding="utf-8"))
    return path


def write_playbacks(study: Study, folder: Path) -> list[Path]:
    """One page per objective and segment, for the best start of its search, named
    ``playback_<objective>_<segment>.html`` in ``folder``, and with a cycle section one per
    strategy's whole cycle (`write_cycle_playbacks`); return their paths."""
    points = task_points(study.cycle)
    paths = []
    for (name, segment), motion in study.best_motions.items():
        path = folder / f"playback_{name}_{segment}.html"
        strategy = f"best start, {study.searches[name][0].objective.label} objective"
        paths.append(export_html(motion, path, points, strategy))
    if study.cycle_study is not None:
        paths += write_cycle_playbacks(study.cycle_study, folder)
    return paths


def write_cycle_playbacks(study: CycleStudy, folder: Path) -> list[Path]:
    """One page per strategy playing its whole first cycle, named
    ``playback_cycle_<strategy>.html`` in ``folder``; return their paths."""
    points = task_points(study.cycle)
    return [
        export_html(motion, folder / f"playback_cycle_{name}.html", points, f"{name} strategy")
        for name, motion in study.firsts.items()
    ]


@contextlib.contextmanager
def served(page: str, address: str = LOCALHOST) -> Iterator:
    """A meshcat visualizer whose server (`redundancy.viz.server`: the HTML ``page`` on
    ``address``, 127.0.0.1 unless asked, ended with this process however it ends) runs for the
    duration of the block; the server process is stopped, and its ports freed, however the block
    ends."""
    meshcat = _meshcat()
    command = [sys.executable, "-u", "-m", "redundancy.viz.server", str(os.getpid()), address]
    # the server's chatter (a line per connection) goes to a file never read, not a pipe
    with tempfile.TemporaryFile() as log:
        pipe = subprocess.PIPE
        server = subprocess.Popen(command, stdin=pipe, stdout=pipe, stderr=log, encoding="utf-8")
        with contextlib.suppress(BrokenPipeError):  # a server that died says why below
            server.stdin.write(page)  # type: ignore[union-attr]
            server.stdin.close()  # type: ignore[union-attr]
        stalled = threading.Timer(STARTUP, server.kill)  # a server that never says where it is
        stalled.start()
        try:
            line = ""
            while not line.startswith("zmq_url=") and server.poll() is None:
                line = server.stdout.readline().strip()  # type: ignore[union-attr]
            stalled.cancel()
            if not line.startswith("zmq_url="):
                log.seek(0)
                said = log.read().decode(errors="replace").strip().splitlines()
                reason = said[-1] if said else "no reason given"
                raise RedundancyError(f"the meshcat server did not start: {reason}")
            # its stdout is not read again: drain it, so that the server never blocks on a pipe
            drain = server.stdout.read  # type: ignore[union-attr]
            threading.Thread(target=drain, daemon=True).start()
            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its address; we do
                vis = meshcat.Visualizer(zmq_url=line[len("zmq_url=") :])
            try:
                yield vis
            finally:
                vis.window.zmq_socket.close(linger=0)
        finally:
            stalled.cancel()
            server.terminate()
            try:
                server.wait(timeout=5)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def play(
    motion: Trajectory,
    points: np.ndarray | None = None,
    announce: Callable[[str], None] = print,
    address: str = LOCALHOST,
    strategy: str | None = None,
) -> None:
    """Serve the playback of ``motion`` on ``address`` (this machine only by default) until
    interrupted (KeyboardInterrupt, which propagates): `export_html`'s page, its scene sent by
    the server, its heading naming ``strategy`` as that page's does. ``announce`` is given the
    page's address once it is served (an IPv6 address in brackets). The server stops when this
    returns or raises."""
    title, heading = _titles(motion, strategy)
    playback = Playback(motion, points)
    viewer = '<script src="main.min.js"></script>'  # meshcat's, beside the page
    live = _html(title, playback.overlay(heading), viewer, "viewer.connect();")
    with served(live, address) as vis:
        _shown(playback, vis)
        url = vis.url()
        host = f"[{address}]" if ":" in address else address  # an IPv6 address, as URLs write it
        announce(url if address == LOCALHOST else url.replace(LOCALHOST, host, 1))
        threading.Event().wait()
