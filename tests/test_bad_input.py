"""The bad-input catalogue: every case ends in one line that names the offending value, exit 2
on the command line (a `RedundancyError` from the API), and never a traceback or an internal
error. The command line runs in-process (`redundancy.cli.main`), as a user's shell would run it,
but without an interpreter start per case."""

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest

import redundancy
from redundancy import (
    VELOCITY,
    Controller,
    GradientProjection,
    RedundancyError,
    Resolver,
    actuator_space,
    configuration_at,
    global_optimum,
    improved_start,
    inverse_kinematics,
    load_robot,
    periodic_optimum,
    repeat,
    return_map,
    shortest_duration,
    simulate,
)
from redundancy.cli import main
from redundancy.planning.tasks import Segment, WorkCycle

CRANE = Path(__file__).parent.parent / "redundancy" / "robots" / "hiab031"
URDF = (CRANE / "hiab031.urdf").read_text()
TASK = (CRANE / "task.toml").read_text()
ROBOT = (CRANE / "robot.toml").read_text()
HYDRAULICS = ROBOT[ROBOT.index("[hydraulics]") :]

# an arm whose turning joint moves no inertia at mid-range: its link has none about the joint's
# axis, and the tip's point mass reaches the axis at mid-range (reach = 0)
AXIS = """<robot name="axis">
  <link name="base"/>
  <joint name="turn" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="arm"><inertial><mass value="10"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="0"/></inertial></link>
  <joint name="reach" type="prismatic"><parent link="arm"/><child link="tip"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="tip"><inertial><mass value="1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
</robot>"""


def _description(**changes) -> str:
    """The crane's robot.toml, pointing at its URDF, with ``changes`` (TOML values) applied."""
    lines = {
        "urdf": f'"{CRANE / "hiab031.urdf"}"',
        "tool_frame": '"tool"',
        "task_axes": '"xz"',
        "payload": "100.0",
        "task": f'"{CRANE / "task.toml"}"',
    } | changes
    return "".join(f"{key} = {value}\n" for key, value in lines.items() if value is not None)


# (name, argv, file contents by name, the message's fragment)
WRONG = ['"heavy"', "true", "[1, 2]", "{a = 1}", "-1", "1e300", "nan", "inf"]
CASES = [
    # command-line options
    *[
        (f"--payload {v}", ["describe", "--payload", v], {}, f"--payload: {v!r} must be a mass")
        for v in ("abc", "nan", "inf", "1e18", "1e308", "", "0x10", "1,5")
    ],
    *[  # argparse reads a leading minus as an option
        (f"--payload {v}", ["describe", "--payload", v], {}, "argument --payload")
        for v in ("-inf", "-1")
    ],
    *[
        (f"--samples {v}", ["study", "--samples", v], {}, f"--samples: {v!r} must be a whole")
        for v in ("0", "-3", "2.5", "abc", "1e3", "", "10001", "1000000000", "nan")
    ],
    *[
        (f"--{option} bad", ["study", f"--{option}", "bad"], {}, f"argument --{option}: invalid")
        for option in ("method", "objective")
    ],
    # said by the command it was given to, with that command's help
    (
        "unknown option",
        ["study", "--bogus"],
        {},
        "redundancy study: error: unrecognized arguments: --bogus; see redundancy study --help",
    ),
    (  # before the command: the command line's own
        "unknown option before the command",
        ["--bogus", "robots"],
        {},
        "redundancy: error: unrecognized arguments: --bogus; see redundancy --help",
    ),
    ("payload with a digit separator", ["describe", "--payload", "1_000"], {}, "'1_000' must be"),
    ("unknown command", ["frobnicate"], {}, "invalid choice: 'frobnicate'"),
    ("unknown robot", ["describe", "--robot", "nope"], {}, "unknown robot 'nope'"),
    ("robot folder", ["describe", "--robot", "/"], {}, "robot '/' is a folder without a"),
    ("missing urdf", ["describe", "--robot", "none.urdf"], {}, "no URDF file at none.urdf"),
    ("missing toml", ["describe", "--robot", "none.toml"], {}, "no robot description at"),
    ("check unknown", ["study", "--check", "x9"], {}, "--check x9: unknown actuators ['x9']"),
    ("check empty", ["study", "--check", ""], {}, "unknown actuators ['']"),
    ("x3init outside", ["play", "--x3init", "5", "--html", "p.html"], {}, "--x3init 5 is outside"),
    ("x3init nan", ["play", "--x3init", "nan", "--html", "p.html"], {}, "--x3init nan is outside"),
    (
        "x3init out of reach",  # inside x3's stroke, but segment 1-2's start is out of reach
        ["play", "--segment", "1-2", "--x3init", "0", "--html", "p.html"],
        {},
        "cannot reach task point [3.5, -0.5] with x3 = 0 mm inside its joint limits: the "
        "closest configuration misses it by 801.5 mm",
    ),
    ("segment unknown", ["play", "--segment", "9-9", "--html", "p.html"], {}, "no segment '9-9'"),
    (
        "listen elsewhere",
        ["play", "--listen", "192.0.2.1"],
        {},
        "--listen: '192.0.2.1' must be an IP address of this machine",
    ),
    ("out is a file", ["study", "--out", "plain"], {"plain": ""}, "--out plain is a file"),
    ("json is a folder", ["study", "--json", "sub"], {"sub/x": ""}, "--json sub is a folder"),
    ("html below a file", ["play", "--html", "plain/p.html"], {"plain": ""}, "not a folder"),
    ("out of other files", ["study", "--out", "mine"], {"mine/notes.txt": "x"}, "did not write"),
    # task files
    ("task missing", ["study", "--task", "none.toml"], {}, "cannot read task file none.toml"),
    ("task binary", ["study", "--task", "t.toml"], {"t.toml": b"\x00\xff\xfe"}, "not UTF-8"),
    ("task not toml", ["study", "--task", "t.toml"], {"t.toml": "[points"}, "not valid TOML"),
    *[
        (
            f"task speed {v}",
            ["study", "--task", "t.toml"],
            {"t.toml": TASK.replace("speed = 0.5", f"speed = {v}")},
            "speed = ",
        )
        for v in ('"heavy"', "true", "[1]", "-1", "11", "1e300", "nan", "inf")
    ],
    *[
        (
            f"task slow {speed} {acceleration}",
            ["study", "--task", "t.toml"],
            {"t.toml": TASK.replace("speed = 0.5", f"speed = {speed}{acceleration}")},
            "a segment may take at most 600 s: give a higher speed",
        )
        for speed, acceleration in [
            ("1e-6", ""),
            ("1e-300", ""),
            ("0.5", '\nprofile = "trapezoidal"\nacceleration = 1e-6'),
            ("0.5", '\nprofile = "trapezoidal"\nacceleration = 1e-300'),
        ]
    ],
    (
        "task speed zero",
        ["study", "--task", "t.toml"],
        {"t.toml": TASK.replace("speed = 0.5", "speed = 0")},
        "speed = 0 must be within (0, 10] (the tool's speed, m/s)",
    ),
    *[
        (
            f"task held {v}",
            ["study", "--task", "t.toml"],
            {"t.toml": TASK.replace('held = ["x3"]', f"held = {v}")},
            "held = ",
        )
        for v in ('"x3"', "3", "[3]", "{x = 3}", "true", "[]", '["x3", "x3"]')
    ],
    (
        "task held unknown",
        ["study", "--task", "t.toml"],
        {"t.toml": TASK.replace('held = ["x3"]', 'held = ["x9"]')},
        "unknown actuators ['x9']",
    ),
    *[
        (
            f"task segments {v}",
            ["study", "--task", "t.toml"],
            {"t.toml": re.sub(r"segments = \[.*\]", f"segments = {v}", TASK)},
            message,
        )
        for v, message in (
            ('"1-2"', 'segments = "1-2" must be a list'),
            ("[12]", "segments = [12] must be a list"),
            ('["1-9"]', "segment '1-9' must be '<from>-<to>'"),
            ('["1"]', "segment '1' must be '<from>-<to>'"),
            ('["1-1"]', "start and end coincide"),
            ("[]", "no segments"),
            # the outputs are named after a segment: no name may lead them out of their folder
            ('[{from = "1", to = "2", name = "../../x"}]', "segment name '../../x' must be"),
            ('[{from = "1", to = "2", name = ".."}]', "segment name '..' must be"),
            ('[{from = "1", to = "2", name = ""}]', "segment name '' must be"),
            ('[{from = "1", to = "2", name = "a\\tb"}]', "segment name 'a\\tb' must be"),
            (f'[{{from = "1", to = "2", name = "{"é" * 51}"}}]', "at most 100 bytes"),
        )
    ],
    (
        "task point named with a slash",
        ["study", "--task", "t.toml"],
        {"t.toml": TASK.replace('"1-2", ', '"a/b-2", ').replace("1 = [", '"a/b" = [')},
        "segment name 'a/b-2' must be",
    ),
    (
        "task segment named with a backslash",
        ["study", "--task", "t.toml"],
        {"t.toml": TASK.replace('"1-2", ', "{from = '1', to = '2', name = 'a\\b'}, ")},
        "segment name 'a\\\\b' must be",
    ),
    *[
        (
            f"task point {v}",
            ["study", "--task", "t.toml"],
            {"t.toml": TASK.replace("1 = [3.5, -0.5]", f"1 = {v}")},
            message,
        )
        for v, message in (
            ('["a", "b"]', '[points] 1 = ["a", "b"] must be a list of finite numbers'),
            ("[3.5, -0.5, 1.0]", "point 1 has 3 coordinates; the robot's task has 2"),
            ("[3.5]", "point 1 has 1 coordinates"),
            ("[nan, 0]", "[points] 1 = [nan, 0] must be a list of finite numbers"),
            ("[inf, 0]", "[points] 1 = [inf, 0] must be a list of finite numbers"),
            ("[1e308, 0]", "point 1: 1e+308 lies beyond ±1000 (m, or degrees for the tool's"),
            ('"3.5, -0.5"', '[points] 1 = "3.5, -0.5" must be a list of finite numbers'),
            ("[true, 0]", "[points] 1 = [true, 0] must be a list of finite numbers"),
            ("[100.0, -0.5]", "cannot follow segment 1-2: its point [100.0, -0.5] m (t = 0 s)"),
        )
    ],
    (
        "task no points",
        ["study", "--task", "t.toml"],
        {"t.toml": 'segments = ["1-2"]\n'},
        "needs a [points] table",
    ),
    # robot descriptions
    *[
        (
            f"robot.toml {key} = {v}",
            ["describe", "--robot", "r.toml"],
            {"r.toml": _description(**{key: v})},
            f"{key} = {v} must be",  # the value as the file writes it: true, not True
        )
        for key in ("urdf", "tool_frame", "task_axes", "task")
        for v in ("3", "true", "[1]", "{a = 1}")
    ],
    *[
        (
            f"robot.toml payload = {v}",
            ["describe", "--robot", "r.toml"],
            {"r.toml": _description(payload=v)},
            "payload = ",
        )
        for v in WRONG
    ],
    *[
        (
            f"robot.toml locked_joints = {v}",
            ["describe", "--robot", "r.toml"],
            {"r.toml": _description(locked_joints=v)},
            message,
        )
        for v, message in (
            ('"boom1_joint"', 'locked_joints = "boom1_joint" must be a list of names'),
            ("[1]", "must be a list of names"),
            ('["nope"]', "locked joints ['nope'] are not joints"),
        )
    ],
    (
        "robot.toml tool unknown",
        ["describe", "--robot", "r.toml"],
        {"r.toml": _description(tool_frame='"nope"')},
        "tool frame 'nope' is not a link",
    ),
    (
        "robot.toml axes unknown",
        ["describe", "--robot", "r.toml"],
        {"r.toml": _description(task_axes='"xq"')},
        "r.toml: task_axes = \"xq\" must be distinct letters among 'x', 'y', 'z'",
    ),
    (
        "robot.toml unknown key",
        ["describe", "--robot", "r.toml"],
        {"r.toml": _description(paylaod="5")},
        "r.toml: unknown keys ['paylaod']; keys: urdf, tool_frame, tool, task_axes, ",
    ),
    (
        "robot.toml tool and tool_frame",
        ["describe", "--robot", "r.toml"],
        {"r.toml": _description(tool='{link = "telescope", xyz = [1.47, 0, 0]}')},
        "r.toml: tool_frame and tool are both given; give one: tool_frame = a link, or tool = ",
    ),
    (
        "robot.toml missing keys",
        ["describe", "--robot", "r.toml"],
        {"r.toml": 'urdf = "x.urdf"\n'},
        "missing keys ['tool_frame', 'task_axes']",
    ),
    (
        "robot.toml not toml",
        ["describe", "--robot", "r.toml"],
        {"r.toml": "urdf ="},
        "not valid TOML",
    ),
    ("robot.toml binary", ["describe", "--robot", "r.toml"], {"r.toml": b"\xff\xfe"}, "not UTF-8"),
    # URDFs and actuator declarations
    (
        "urdf broken xml",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": "<robot><link"},
        "b.urdf line 1: not readable XML: Couldn't find end of Start Tag link",
    ),
    (
        "urdf not a robot",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": "<foo/>"},
        "not a valid URDF: Could not find the 'robot' element",
    ),
    *[
        (
            f"attachment xyz {v}",
            ["describe", "--robot", "b.urdf"],
            {"b.urdf": re.sub(r'(<attachment link="column" xyz=")[^"]*', rf"\g<1>{v}", URDF)},
            f'<attachment link="column" xyz="{v}"/> must be',
        )
        for v in ("1 2", "a b c", "1 2 3 4", "", "nan 0 0", "1,2,3")
    ],
    (
        "attachment link unknown",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace('<attachment link="column"', '<attachment link="nope"', 1)},
        "attached to link 'nope', which does not exist",
    ),
    (
        "one attachment",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": re.sub(r'\s*<attachment link="column"[^>]*/>', "", URDF, count=1)},
        "missing <attachment> for rod",
    ),
    *[
        (
            f"offset {v}",
            ["describe", "--robot", "b.urdf"],
            {"b.urdf": re.sub(r'<offset value="[^"]*"/>', f"<offset {v}/>", URDF)},
            f"<offset{' ' + v if v else ''}/> must be a finite number",
        )
        for v in ("", 'value=""', 'value="abc"', 'value="nan"', 'value="inf"')
    ],
    *[
        (
            f"stroke {v}",
            ["describe", "--robot", "b.urdf"],
            {"b.urdf": URDF.replace('<stroke lower="0.83"', f"<stroke {v}", 1)},
            message,
        )
        for v, message in (
            ('lower="abc"', '<stroke lower="abc" upper="1.375"/> must be [lower, upper]'),
            ('lower="2.0"', '<stroke lower="2.0" upper="1.375"/> must be [lower, upper]'),
            ('lower="nan"', '<stroke lower="nan" upper="1.375"/> must be [lower, upper]'),
        )
    ],
    (
        "unknown kind",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace("redundancy/LinearCylinder", "redundancy/Nope", 1)},
        '"redundancy/Nope" is not an actuator kind; kinds: ',
    ),
    (
        "missing joint",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace('<joint name="boom1_joint"/>', '<joint name="nope"/>', 1)},
        "drives joint 'nope', which does not exist",
    ),
    (
        "joint driven twice",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace('<joint name="boom2_joint"/>', '<joint name="boom1_joint"/>', 1)},
        "joint 'boom1_joint' is driven twice",
    ),
    (
        "actuator named otherwise",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace('<actuator name="x1">', '<actuator name="lift">', 1)},
        """b.urdf: <transmission name='x1'> <actuator name="lift"> must be named 'x1': """,
    ),
    (
        "two actuators",
        ["describe", "--robot", "b.urdf"],
        {"b.urdf": URDF.replace("</actuator>", '</actuator><actuator name="x1"/>', 1)},
        "b.urdf: <transmission name='x1'> has 2 <actuator> elements; it declares one actuator",
    ),
    (
        "cylinder attribute",
        ["describe", "--robot", "b.urdf"],
        {
            "b.urdf": URDF.replace(
                '<stroke lower="0.83"', '<cylinder colour="red"/><stroke lower="0.83"', 1
            )
        },
        "unknown attributes ['colour']",
    ),
    # physical validation
    (
        "inverted joint limits",
        ["describe", "--robot", "b.urdf"],
        {
            "b.urdf": re.sub(
                r'(<joint name="boom1_joint".*?<limit lower=")([^"]*)(" upper=")([^"]*)',
                r"\g<1>\g<4>\g<3>\g<2>",
                URDF,
                count=1,
                flags=re.S,
            )
        },
        "inverted: boom1_joint [2.6145, 0.827286]",
    ),
    (
        "attachment far away",
        ["check", "--robot", "m.toml"],
        {
            "m.urdf": URDF.replace(
                'link="boom1" xyz="0.369583691280232', 'link="boom1" xyz="1e300'
            ),
            "m.toml": _description(urdf='"m.urdf"'),
        },
        'rod <attachment link="boom1" xyz="1e300 0 -0.0691657078303828"/>: xyz must be within '
        "±100 m of the link's frame: 1e+300 m is beyond",
    ),
    (
        "no masses",
        ["study", "--robot", "m.toml", "--objective", "energy"],
        {
            "m.urdf": re.sub(r"<inertial>.*?</inertial>", "", URDF, flags=re.S),
            "m.toml": _description(urdf='"m.urdf"', payload="0"),
        },
        "kinematic only: links boom1, boom2, telescope",
    ),
    # the slew held, the boom's cylinders move the tool in its vertical plane alone: a 3-D
    # task cannot be followed (the study said no start was reachable, play ran from one)
    (
        "held slew on a 3-D task",
        ["study", "--robot", "hiab031_slewing", "--task", "t.toml"],
        {
            "t.toml": 'held = ["slew"]\nsegments = ["a-b"]\n[points]\na = [2.2, 0.0, 1.8]\n'
            "b = [2.0, 0.0, 1.8]\n"
        },
        "t.toml: held: holding slew leaves x1, x2, x3 at most 2 of the task's 3 directions to "
        "move the tool in, anywhere in the joint ranges: they reach a task point at isolated held "
        'values at most, which no search can sample; hold other actuators, e.g. held = ["x3"]',
    ),
    (
        "task axis never moved along",
        ["study", "--robot", "r.toml", "--task", "t.toml"],
        {
            "r.toml": _description(task_axes='"xy"'),
            "t.toml": 'segments = ["a-b"]\n[points]\na = [3.5, 0.0]\nb = [1.0, 0.0]\n',
        },
        "cannot move its tool along y at the start of segment a-b [3.5, 0.0]: the task Jacobian",
    ),
    (
        "mass on a joint's axis",
        ["describe", "--robot", "axis.urdf"],
        {"axis.urdf": AXIS},
        "axis: M(q) is singular at q = [0, 0]: nothing beyond joints ['turn'] has mass off their "
        "axes or inertia about them",
    ),
    (
        "zero masses",
        ["study", "--robot", "m.toml", "--objective", "energy", "--samples", "10", "--cycles", "0"],
        {
            "m.urdf": re.sub(r'<mass value="[^"]*"/>', '<mass value="0"/>', URDF),
            "m.toml": _description(urdf='"m.urdf"', payload="0"),
        },
        "kinematic only: links tool have no <inertial> and links boom1, boom2, telescope have a "
        "zero <mass> in m.urdf, and ",
    ),
    *[
        (
            f"link {new}",
            ["describe", "--robot", "r.toml"],
            {"e.urdf": URDF.replace(old, new, 1), "r.toml": _description(urdf='"e.urdf"')},
            f"e.urdf: link 'boom1' {written} must be {meaning}",
        )
        for old, new, written, meaning in [
            *[
                (
                    '<mass value="80"/>',
                    f'<mass value="{v}"/>',
                    f'<mass value="{v}"/>',
                    "a number within [0, 1e+06] (the link's mass, kg)",
                )
                for v in ("nan", "inf", "-80", "abc", "", "1e300")
            ],
            *[
                ('<origin xyz="0.8 0 0"/>', origin, origin, 'xyz="x y z" rpy="r p y"')
                for origin in ('<origin xyz="nan 0 0"/>', '<origin rpy="0 1"/>')
            ],
            *[
                (
                    'iyy="17.0666666666667"',
                    f'iyy="{v}"',
                    f'<inertia ixx="0" ixy="0" ixz="0" iyy="{v}" iyz="0" izz="17.0666666666667"/>',
                    "six numbers ixx, ixy, ixz, iyy, iyz, izz within ±1e+08",
                )
                for v in ("nan", "inf", "abc", "1e300")
            ],
        ]
    ],
    (
        "link negative mass, energy",
        ["study", "--robot", "r.toml", "--objective", "energy", "--samples", "10", "--cycles", "0"],
        {
            "e.urdf": URDF.replace('<mass value="80"/>', '<mass value="-80"/>', 1),
            "r.toml": _description(urdf='"e.urdf"'),
        },
        """e.urdf: link 'boom1' <mass value="-80"/> must be a number within [0, 1e+06]""",
    ),
    *[
        (
            f"link {new}",
            [*command, "--robot", "r.toml"],
            {"e.urdf": URDF.replace(old, new, 1), "r.toml": _description(urdf='"e.urdf"')},
            f"e.urdf: link 'boom1' {written} is not a body's rotational inertia: its principal "
            f"moments {moments} kg·m² must be ≥ 0 and each at most the sum of the other two",
        )
        for command, old, new, written, moments in [
            (
                ["describe"],
                'iyy="17.0666666666667"',
                'iyy="-17"',
                '<inertia ixx="0" ixy="0" ixz="0" iyy="-17" iyz="0" izz="17.0666666666667"/>',
                "[-17, 0, 17.07]",
            ),
            (
                ["study", "--objective", "energy", "--samples", "10", "--cycles", "0"],
                'iyy="17.0666666666667"',
                'iyy="-1700"',
                '<inertia ixx="0" ixy="0" ixz="0" iyy="-1700" iyz="0" izz="17.0666666666667"/>',
                "[-1700, 0, 17.07]",
            ),
            (
                ["describe"],
                'ixx="0" ixy="0"',
                'ixx="40" ixy="0"',
                '<inertia ixx="40" ixy="0" ixz="0" iyy="17.0666666666667" iyz="0" '
                'izz="17.0666666666667"/>',
                "[17.07, 17.07, 40]",
            ),
            (
                ["describe"],
                'ixx="0" ixy="0"',
                'ixx="0" ixy="5"',
                '<inertia ixx="0" ixy="5" ixz="0" iyy="17.0666666666667" iyz="0" '
                'izz="17.0666666666667"/>',
                "[-1.357, 17.07, 18.42]",
            ),
        ]
    ],
    (
        "link without mass",
        ["describe", "--robot", "r.toml"],
        {
            "e.urdf": URDF.replace('<mass value="80"/>', "", 1),
            "r.toml": _description(urdf='"e.urdf"'),
        },
        "e.urdf: link 'boom1': <inertial> has no <mass>; it needs one: a number within [0, 1e+06]",
    ),
    (
        "unreachable end",
        ["study", "--task", "t.toml"],
        {"t.toml": TASK.replace("2 = [1.0, -0.5]", "2 = [100.0, -0.5]")},
        "cannot follow segment 1-2: its point [9.53125, -0.5] m (t = 12.1 s) is out of reach "
        "inside the joint limits, missed by 5658 mm; so is its end [100.0, -0.5] m, missed by "
        "96126 mm",
    ),
    # hydraulics files
    (
        "hydraulics missing",
        ["describe", "--hydraulics", "none.toml"],
        {},
        "cannot read hydraulics file none.toml",
    ),
    (
        "hydraulics no table",
        ["describe", "--hydraulics", "h.toml"],
        {"h.toml": "a = 1\n"},
        "no [hydraulics] table",
    ),
    *[
        (
            f"hydraulics {key} = {v}",
            ["describe", "--hydraulics", "h.toml"],
            {"h.toml": re.sub(rf"(?m)^{key} = [^#\n]*", f"{key} = {v}", HYDRAULICS, count=1)},
            f"{key} = {v} must be within {bounds}",
        )
        for key, v, bounds in [
            ("bore", "0.001", "[5, 1000] (bore D, mm); did you give m? 1 m = 1000 mm"),
            ("bore", "2000.0", "[5, 1000] (bore D, mm)"),
            ("max_speed", "50.0", "[0.001, 10] (maximum speed, m/s); did you give mm/s?"),
            ("max_speed", "1e-300", "[0.001, 10] (maximum speed, m/s)"),
            ("max_acceleration", "1e-300", "[0.001, 100] (maximum acceleration, m/s²)"),
        ]
    ],
    (
        "hydraulics not a table",
        ["describe", "--hydraulics", "h.toml"],
        {"h.toml": "hydraulics = 3\n"},
        "h.toml: [hydraulics] = 3 must be a table",
    ),
    *[
        (
            f"hydraulics {key} = {v}",
            ["describe", "--hydraulics", "h.toml"],
            {"h.toml": re.sub(rf"(?m)^{key} = [^#\n]*", f"{key} = {v}", HYDRAULICS, count=1)},
            f"{key} = ",
        )
        for key in ("ls_margin", "relief", "pump_flow", "bore", "max_speed")
        for v in ('"x"', "true", "-1", "nan", "[1]")
    ],
    (
        "hydraulics supply",
        ["describe", "--hydraulics", "h.toml"],
        {"h.toml": HYDRAULICS.replace('supply = "LS"', 'supply = "XX"')},
        '[hydraulics] supply = "XX" must be one of "LS", "CP"',
    ),
    (
        "hydraulics rod too big",
        ["describe", "--hydraulics", "h.toml"],
        {"h.toml": HYDRAULICS.replace("rod = 45.0", "rod = 90.0")},
        "0 ≤ rod < bore",
    ),
    # implausible units: the value, its range and the likely mistake
    *[
        (
            f"hydraulics {key} = {v}",
            ["describe", "--hydraulics", "h.toml"],
            {"h.toml": re.sub(rf"(?m)^{key} = [^#\n]*", f"{key} = {v}", HYDRAULICS, count=1)},
            f"[hydraulics] {key} = {v} must be within [{bounds}] ({meaning}); did you give {unit}",
        )
        for key, v, bounds, meaning, unit in [
            ("relief", "21000000.0", "1, 1000", "relief pressure, bar", "psi or Pa? 1 bar = 14.5"),
            ("relief", "3600.0", "1, 1000", "relief pressure, bar", "psi or Pa? 1 bar = 14.5 psi"),
            ("tank", "200000.0", "0, 1000", "tank pressure p_T, bar", "psi or Pa?"),
            ("ls_margin", "0.5", "1, 1000", "LS margin Δp_LS, bar", "MPa? 1 MPa = 10 bar"),
            ("pump_flow", "0.0016", "0.1, 10000", "pump's maximum flow, L/min", "m³/s?"),
        ]
    ],
    *[
        (name, ["describe", "--robot", "b.urdf"], {"b.urdf": URDF.replace(old, new, 1)}, fragment)
        for name, old, new, fragment in [
            (
                "stroke in mm",
                '<stroke lower="0.83" upper="1.375"/>',
                '<stroke lower="830" upper="1375"/>',
                '<stroke lower="830" upper="1375"/>: 830 m is beyond 100 m, longer than any '
                "cylinder; did you give mm? 1 m = 1000 mm",
            ),
            (
                "stroke of a negative length",
                '<stroke lower="0.83"',
                '<stroke lower="-0.5"',
                '<stroke lower="-0.5" upper="1.375"/>: a cylinder\'s length is at least 0',
            ),
            (
                "attachment in mm",
                'xyz="0.383427387292961 0 -0.963510476680816"',
                'xyz="383 0 -964"',
                '<attachment link="column" xyz="383 0 -964"/>: xyz must be within ±100 m of '
                "the link's frame: 383 m is beyond; did you give mm? 1 m = 1000 mm (the "
                "cylinder's base point)",
            ),
        ]
    ],
    (
        "tool point in mm",
        ["describe", "--robot", "r.toml"],
        {"r.toml": _description(tool_frame=None, tool='{link = "telescope", xyz = [1470, 0, 0]}')},
        "r.toml: [tool] xyz = [1470, 0, 0] must be within ±100 m of the link's frame: 1470 m is "
        "beyond; did you give mm? 1 m = 1000 mm",
    ),
    (
        "map bore in mm",
        ["map", "m.toml"],
        {"m.toml": '[task]\n[grid]\nbore = {actuator = "x1", values = [80, 90]}\n'},
        "m.toml: [grid.bore] values = [80, 90] must be within [0.005, 1]; did you give mm? "
        "1 m = 1000 mm",
    ),
    (
        "map attachment in mm",
        ["map", "m.toml"],
        {
            "m.toml": '[task]\n[grid]\nattachment = {actuator = "x1", end = "base", axis = "x", '
            "values = [383]}\n"
        },
        "m.toml: [grid.attachment] values = [383] must be within [-100, 100]; did you give mm?",
    ),
    # files that are no files: one line, not MemoryError
    *[
        (f"{what} /dev/zero", argv, files, fragment)
        for what, argv, files, fragment in [
            ("task", ["study", "--task", "/dev/zero"], {}, "/dev/zero: not a task file: not a "),
            ("hydraulics", ["describe", "--hydraulics", "/dev/zero"], {}, "not a hydraulics file"),
            ("map", ["map", "/dev/zero"], {}, "/dev/zero: not a map file: not a regular file"),
            (
                "csv",
                ["study", "--task", "t.toml"],
                {"t.toml": 'segments = [{ csv = "/dev/zero" }]\n'},
                "/dev/zero: not a CSV file: not a regular file",
            ),
        ]
    ],
    # paths out of reach: refused before any simulation, naming the point and the miss
    *[
        (
            f"{command} path {name}",
            [command, "--task", "t.toml"],
            {"t.toml": f'speed = 0.5\nsegments = ["a-b"]\n[points]\na = {a}\nb = {b}\n'},
            f"cannot follow segment a-b: its point {point}",
        )
        for command in ("study", "play")
        for name, a, b, point in [
            ("end 100 m away", [3.5, -0.5], [100.0, -0.5], "[9.53125, -0.5]"),
            ("middle", [0.0, -1.0], [2.0, 3.0], "[0.625, 0.25] m (t = 2.8 s)"),
        ]
    ],
    # design maps: argument errors and families that fail before any worker starts
    *[
        (f"map --workers {v}", ["map", "m.toml", "--workers", v], {}, "must be a whole number")
        for v in ("0", "2.5", "x", "5000")
    ],
    # 4096 local workers would hold over 1.2 TB: refused before the first one starts
    (
        "map --workers beyond memory",
        ["map", "m.toml", "--workers", "4096"],
        {"m.toml": "[task]\n"},
        "--workers 4096: that many local worker processes need about 1228.8 GB",
    ),
    *[
        (f"map --timeout {v}", ["map", "m.toml", "--timeout", v], {}, "must be seconds")
        for v in ("0", "nan", "inf", "x", "1e9")
    ],
    ("map missing family", ["map", "none.toml"], {}, "cannot read map file none.toml"),
    ("map binary family", ["map", "m.toml"], {"m.toml": b"\x00\xff"}, "not UTF-8"),
    *[
        (f"map {name}", ["map", "m.toml"], {"m.toml": text}, fragment)
        for name, text, fragment in [
            ("no segments", "name = 'x'\n", "give the segments by one table"),
            ("objectives string", 'objectives = "velocity"\n[task]\n', "must be a list of"),
            ("held unknown", 'held = ["x9"]\n[task]\n', "unknown actuators ['x9']"),
            (  # refused before any worker starts, naming the map file that holds it
                "held slew",
                'robot = "hiab031_slewing"\nheld = ["slew"]\n[task]\n',
                "m.toml: held: holding slew leaves x1, x2, x3 at most 2 of the task's 3 directions",
            ),
            (
                "workspace axis",
                "[workspace]\nlength = 1\ndirection = [1, 0]\n[workspace.grid]\nx = 2\ny = 2\n",
                "task axes: x, z",
            ),
            (
                "workspace direction",
                "[workspace]\nlength = 1\ndirection = [0, 0]\n[workspace.grid]\nx = 2\nz = 2\n",
                "must be nonzero",
            ),
            ("length", "[workspace]\nlength = -1\n", "length = -1 must be within"),
            ("task segment", '[task]\nsegments = ["9-9"]\n', "no segment '9-9'"),
            ("grid speed", "[task]\n[grid]\nspeed = [0.5, 20]\n", "must be within [1e-06, 10]"),
            (
                "grid attachment end",
                '[task]\n[grid]\nattachment = {actuator = "x1", '
                'end = "top", axis = "x", values = [0.1]}\n',
                '[grid.attachment] end = "top" must be one of "base", "rod"',
            ),
            (
                "grid attachment kind",
                '[task]\n[grid]\nattachment = {actuator = "x3", '
                'end = "base", axis = "x", values = [0.1]}\n',
                "not a LinearCylinder",
            ),
            (
                "grid bore below rod",
                '[task]\n[grid]\nbore = {actuator = "x1", values = [0.01]}\n',
                "must all exceed the rod",
            ),
            ("energy flag", "energy = 1\n[task]\n", "energy = 1 must be true or false"),
            (
                "workspace key",
                "[workspace]\nlength = 1\ndirection = [-1, 0]\ncolour = 1\n[workspace.grid]\n"
                "x = 2\nz = 2\n",
                "[workspace]: unknown keys ['colour']; keys: length, direction, speed, grid",
            ),
            (
                "task key",
                "[task]\nfiles = 't.toml'\n",
                "m.toml: [task]: unknown keys ['files']; keys: file, segments",
            ),
            (
                "grid attachment key",
                '[task]\n[grid]\nattachment = {actuator = "x1", end = "base", axis = "x", '
                "values = [0.33], colour = 1}\n",
                "[grid.attachment]: unknown keys ['colour']; keys: actuator, end, axis, values",
            ),
            (
                "grid bore key",
                '[task]\n[grid]\nbore = {actuator = "x1", values = [0.08], rod = 0.04}\n',
                "[grid.bore]: unknown keys ['rod']; keys: actuator, values",
            ),
            (
                "grid range key",
                "[task]\n[grid]\npayload = {from = 0, to = 500, count = 3, step = 250}\n",
                "[grid.payload]: unknown keys ['step']; keys: from, to, count",
            ),
            (
                "objectives twice",
                'objectives = ["velocity", "velocity"]\n[task]\n',
                'objectives = ["velocity", "velocity"] names "velocity" more than once; give each '
                "once (objectives: velocity, energy",
            ),
            (
                "task segments twice",
                '[task]\nsegments = ["1-2", "1-2"]\n',
                'segments = ["1-2", "1-2"] names "1-2" more than once',
            ),
            (
                "too many problems",
                "[task]\n[grid]\npayload = {from = 0, to = 1, count = "
                "100000}\nspeed = {from = 0.1, to = 1, count = 100000}\n",
                "split a larger",
            ),
            (
                "too many workspace starts",
                "name = 'big'\nobjectives = ['velocity']\n[workspace]\nlength = 1.0\n"
                "direction = [-1.0, 0.0]\n[workspace.grid]\nx = [0.5, 4.0, 100000]\n"
                "z = [-1.0, 3.0, 100000]\n",
                "the family has 10,000,000,000 problems; it must have at most 2,000,000",
            ),
        ]
    ],
    *[
        (
            f"map --scheduler {v}",
            ["map", "m.toml", "--scheduler", v],
            {"m.toml": "[task]\n"},
            f"--scheduler {v!r} is not a scheduler's address; give tcp://HOST:PORT",
        )
        for v in ("not a url", "http://127.0.0.1:1", "tcp://127.0.0.1", "tcp://h:99999", "")
    ],
    (
        "map out is a file",
        ["map", "m.toml", "--out", "f"],
        {"m.toml": "[task]\n", "f": ""},
        "--out f is a file",
    ),
]


@pytest.mark.parametrize(
    ("argv", "files", "fragment"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_bad_command_line_input_is_one_line(tmp_path, monkeypatch, capsys, argv, files, fragment):
    monkeypatch.chdir(tmp_path)
    for name, content in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
    try:
        status = main([*argv, "--quiet"] if argv[0] == "study" else argv)
    except SystemExit as exit:
        status = exit.code
    errors = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in errors if not line.startswith("redundancy: note:")]
    assert status == 2, errors
    assert len(errors) == 1, errors
    assert "internal error" not in errors[0] and "Traceback" not in errors[0]
    assert fragment in errors[0], errors[0]
    if files:  # the line names the file to fix, unless an option is what is wrong
        named = [name for name in files if Path(name).name in errors[0]]
        assert named or errors[0].startswith("redundancy: error: --"), errors[0]


def test_a_message_quotes_no_more_than_an_excerpt_of_a_file(tmp_path, monkeypatch, capsys):
    """A CSV task naming a file that is no polyline (a system file, say) is refused in one line
    that quotes at most the start of the offending cell, not the file's line."""
    monkeypatch.chdir(tmp_path)
    secret = "daemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin:and-the-rest-of-the-line"
    (tmp_path / "passwd").write_text(f"root:x:0:0:root:/root:/bin/bash\n{secret}\n")
    (tmp_path / "t.toml").write_text('segments = [{ csv = "passwd" }]\n')
    assert main(["study", "--task", "t.toml", "--quiet"]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 1 and "passwd line 2: cell 1 ('daemon:x:1:1:daemon:" in errors[0]
    assert "nologin" not in errors[0] and "rest-of-the-line" not in errors[0], errors[0]


@pytest.fixture(scope="module")
def crane():
    return load_robot("hiab031")


STATE = [1.6, 1.0, 0.5]
FAR = np.array([1.7, 1.0, 1e200])  # finite, but the telescope out 1e200 m: every product overflows
ROBOT_FIRST = [  # each public function that takes a robot first, with the rest of its arguments
    ("actuator_space", lambda r: (STATE,)),
    ("simulate", lambda r: (VELOCITY.resolver, _segment(r), np.array([STATE]))),
    ("simulate_path", lambda r: (VELOCITY.resolver, _segment(r), np.array([STATE]))),
    ("improved_start", lambda r: (_segment(r), VELOCITY)),
    ("improved_starts", lambda r: (_segment(r), (VELOCITY,))),
    ("default_start", lambda r: (_segment(r),)),
    ("inverse_kinematics", lambda r: (_segment(r).start, ["x3"], [[1.0]])),
    ("configuration_at", lambda r: (_segment(r).start, {"x3": 1.0})),
    ("global_optimum", lambda r: (_segment(r),)),
    ("integral_optimum", lambda r: (_segment(r), "energy", "x3")),
    ("energy_optimum", lambda r: (_segment(r), None, "x3")),
    ("plan_cycle", lambda r: (_cycle(r),)),
    ("improved_cycle_start", lambda r: (_cycle(r),)),
    ("periodic_optimum", lambda r: (_cycle(r), None)),
    ("repeat", lambda r: (_cycle(r), VELOCITY.resolver, np.array(STATE))),
    ("return_map", lambda r: (_cycle(r), VELOCITY.resolver)),
    ("run_cycle", lambda r: (_cycle(r),)),
    ("run_study", lambda r: (_cycle(r),)),
    ("check", lambda r: ()),
    ("with_tool_angle", lambda r: ()),
    ("Controller", lambda r: (VELOCITY.resolver,)),
]
API = [
    *[
        (
            f"{name} of a robot's name",
            lambda r, name=name, rest=rest: getattr(redundancy, name)("hiab031", *rest(r)),
            "robot must be a Robot, as load_robot(name) gives one; got 'hiab031'",
        )
        for name, rest in ROBOT_FIRST
    ],
    *[
        (
            f"resolve ẏ {velocities!r}",
            lambda r, v=velocities: VELOCITY.resolver.resolve(actuator_space(r, STATE), v),
            "y_dot must be finite numbers of shape (1, 2), a row per state",
        )
        for velocities in ([[np.nan, 0.0]], [[0.1]], [0.1, 0.0, 0.0], "ab", np.zeros((2, 2)))
    ],
    (
        "controller step far outside the joints' limits",
        lambda r: Controller(r, VELOCITY.resolver).step(FAR, np.array([0.1, 0.0])),
        "the step at q = [1.7, 1, 1e+200] for ẏ = [0.1, 0] is not finite",
    ),
    (
        "resolver step far outside the joints' limits",
        lambda r: VELOCITY.resolver.step(r, FAR, np.array([0.1, 0.0])),
        "the step at q = [1.7, 1, 1e+200] for ẏ = [0.1, 0] is not finite",
    ),
    (
        "controller state far outside the joints' limits",
        lambda r: Controller(r, VELOCITY.resolver).state(FAR),
        "M(q) is not finite at q = [1.7, 1, 1e+200]: its numbers overflow",
    ),
    *[
        (
            f"gradient projection gain {gain!r}",
            lambda r, gain=gain: GradientProjection(gain),
            f"gain must be a number within [0, 1000] m²/s (tuned: 0.07); got {gain!r}",
        )
        for gain in (np.nan, np.inf, 1e308, -0.1, "0.1", True)
    ],
    ("load_robot payload text", lambda r: load_robot("hiab031", payload="abc"), 'payload = "abc"'),
    ("load_robot payload nan", lambda r: load_robot("hiab031", payload=np.nan), "payload = nan"),
    ("load_robot payload huge", lambda r: load_robot("hiab031", payload=1e18), "payload = 1e+18"),
    ("load_robot robot int", lambda r: load_robot(3), "robot must be a name or a path"),
    (
        "load_robot axes",
        lambda r: load_robot("hiab031", task_axes="xq"),
        'load_robot: task_axes = "xq" must be distinct letters',
    ),
    (
        "forces of one row for two states",  # one row serves a batch of one alone
        lambda r: actuator_space(r, [[1.6, 1.0, 0.5], [1.7, 1.0, 0.5]]).forces(np.zeros(3)),
        "x_ddot must be finite numbers of shape (2, 3), a row per state",
    ),
    ("space of a wrong shape", lambda r: actuator_space(r, [1.0, 2.0]), "q must have shape"),
    ("space of nan", lambda r: actuator_space(r, [np.nan, 1.0, 0.5]), "NaN or infinite"),
    ("space at a singularity", lambda r: actuator_space(r, [0.0, 1.0, 0.5]), "singular at q"),
    ("space of text", lambda r: actuator_space(r, ["a", "b", "c"]), "q must be 3 numbers"),
    ("space of complex", lambda r: actuator_space(r, [1.6 + 1j, 1.0, 0.5]), "q must be 3 numbers"),
    (
        "load_robot hydraulics int",
        lambda r: load_robot("hiab031", hydraulics=3),
        "hydraulics must be the path of a TOML file with a [hydraulics] table; got int 3",
    ),
    (
        "improved_start of a segment's name",
        lambda r: improved_start(r, "1-2", VELOCITY),
        "segment must be a Segment or a Chain (e.g. cycle['1-2']",
    ),
    (
        "improved_start of an unknown objective",
        lambda r: improved_start(r, _segment(r), "speed"),
        "unknown objective 'speed'; objectives: velocity, energy",
    ),
    (
        "improved_start of an objective of the wrong type",
        lambda r: improved_start(r, _segment(r), 3),
        "unknown objective 3",
    ),
    (
        "global_optimum of a segment's name",
        lambda r: global_optimum(r, "1-2"),
        "segment must be a Segment or a Chain",
    ),
    (
        "step of nan",
        lambda r: VELOCITY.resolver.step(r, np.array([1.7, 1.0, 0.7]), np.array([np.nan, 0.0])),
        "y_dot contains NaN",
    ),
    (
        "step of three task velocities",
        lambda r: VELOCITY.resolver.step(r, np.array([1.7, 1.0, 0.7]), np.zeros(3)),
        "y_dot must have shape (2,)",
    ),
    (
        "step of two states",
        lambda r: VELOCITY.resolver.step(r, np.ones((2, 3)), np.zeros(2)),
        "a step takes one q (3,) and one y_dot (2,)",
    ),
    (
        "step at a singularity",
        lambda r: VELOCITY.resolver.step(r, np.zeros(3), np.array([1.0, 1.0])),
        "actuator Jacobian A is singular at q = [0.0, 0.0, 0.0]",
    ),
    (
        "samples 2.5",
        lambda r: improved_start(r, _segment(r), VELOCITY, samples=2.5),
        "samples must be a whole number",
    ),
    (
        "samples huge",
        lambda r: improved_start(r, _segment(r), VELOCITY, samples=10**9),
        "samples must be a whole number within [1, 10,000]",
    ),
    (
        "unknown method",
        lambda r: improved_start(r, _segment(r), VELOCITY, method="x"),
        "unknown method 'x'",
    ),
    (
        "held twice",
        lambda r: improved_start(r, _segment(r), VELOCITY, held=["x3", "x2"]),
        "hold that many",
    ),
    (
        "simulate bad method",
        lambda r: simulate(
            r, VELOCITY.resolver, _segment(r), np.array([[1.6, 1.0, 0.5]]), method="euler"
        ),
        "unknown method 'euler'",
    ),
    (
        "simulate bad step",
        lambda r: simulate(
            r, VELOCITY.resolver, _segment(r), np.array([[1.6, 1.0, 0.5]]), time_step=-1
        ),
        "time_step must be a finite number > 0",
    ),
    *[
        (
            f"simulate {name} = inf",
            lambda r, name=name: simulate(
                r, VELOCITY.resolver, _segment(r), np.array([[1.6, 1.0, 0.5]]), **{name: np.inf}
            ),
            f"{name} = inf",
        )
        for name in ("tolerance", "gain", "time_step")
    ],
    (
        "simulate no starts",
        lambda r: simulate(r, VELOCITY.resolver, _segment(r), np.zeros((0, 3))),
        "starts must hold at least one configuration, (3,)",
    ),
    *[
        (
            f"improved_start tolerance {tolerance!r}",
            lambda r, tolerance=tolerance: improved_start(
                r, _segment(r), VELOCITY, tolerance=tolerance
            ),
            f"tolerance must be a finite number > 0 (m or rad); got {tolerance!r}",
        )
        for tolerance in ("abc", np.inf, np.nan, 0.0)
    ],
    (
        "improved_start samples True",
        lambda r: improved_start(r, _segment(r), VELOCITY, samples=True),
        "samples must be a whole number within [1, 10,000]; got True",
    ),
    ("no hydraulics", lambda r: load_robot("panda").circuit(), "declare a [hydraulics] table"),
    *[
        (
            f"held value {value!r}",
            lambda r, value=value: configuration_at(r, [3.5, -0.5], {"x3": value}),
            f"held must be {{actuator: value}}, values numbers; got {{'x3': {value!r}}}",
        )
        for value in ("0.9", None, True)
    ],
    (
        "held outside its stroke",
        lambda r: configuration_at(r, [3.5, -0.5], {"x3": 5.0}),
        "x3 = 5000 mm is outside its stroke [0 mm, 1090 mm]",
    ),
    (
        "held values as text",
        lambda r: configuration_at(r, [3.5, -0.5], {"x3": "a"}),
        "held must be {actuator: value}, values numbers; got {'x3': 'a'}",
    ),
    (
        "periodic margin negative",
        lambda r: periodic_optimum(r, _cycle(r), None, margin=-1.0),
        "margin must be within [0, 0.2725] m; got -1.0",
    ),
    (
        "repetitions from two starts",
        lambda r: repeat(r, _cycle(r), VELOCITY.resolver, np.ones((2, 3)), cycles=1),
        "start must be one configuration (3,): repetitions run one after another",
    ),
    (
        "timing a failed motion",
        lambda r: shortest_duration(simulate(r, VELOCITY.resolver, _segment(r), np.zeros(3))),
        "motion 0 along segment 1-2 failed, where A turned singular or an actuator could not be "
        "evaluated (a cylinder of zero length, a linkage that cannot close), or where its steps "
        "shrank to a crawl (2,000 steps short of the end, or 50 in a row at a singular J_H: the "
        "law chattering, as where the path leaves the arm's reach): it has no path to time",
    ),
    (
        "forces of nan",
        lambda r: actuator_space(r, [1.6, 1.0, 0.5]).forces([[np.nan, 0.0, 0.0]]),
        "x_ddot must be finite numbers of shape",
    ),
    (
        "a law of one's own whose step overflows",  # named as the law's, not as a ẋ given
        lambda r: _Overflowing().step(r, [1.6, 1.0, 0.5], [0.5, 0.0]),
        "overflowing: the step at q = [1.6, 1, 0.5] for ẏ = [0.5, 0] is not finite: the law's "
        "numbers overflow",
    ),
    (
        "joint velocities of nan",
        lambda r: actuator_space(r, [1.6, 1.0, 0.5]).joint_velocities([[0.1, np.nan, 0.0]]),
        "x_dot must be finite numbers of shape (1, 3), a row per state; got [[0.1, nan, 0.0]]",
    ),
    (
        "segment at infinite speed",
        lambda r: Segment("a", np.array([3.5, -0.5]), np.array([1.0, -0.5]), np.inf),
        "segment a: speed must be > 0 and ≤ 10 m/s; got inf",
    ),
    (
        "segment of text",
        lambda r: Segment("a", np.array(["a", "b"]), np.array([1.0, -0.5]), 0.5),
        "segment a: start must be finite task coordinates, shape (m,)",
    ),
    (
        "held as a number",
        lambda r: improved_start(r, _segment(r), VELOCITY, held=3),
        "actuators must be given by name, e.g. 'x3'; got 3",
    ),
    (
        "simulate a step too fine",
        lambda r: simulate(
            r, VELOCITY.resolver, _segment(r), np.array([[1.6, 1.0, 0.5]]), time_step=1e-9
        ),
        "time_step 1e-09 s makes 5,000,000,000 intervals of segment 1-2 (5 s); at most",
    ),
    (
        "simulate a step as text",
        lambda r: simulate(
            r, VELOCITY.resolver, _segment(r), np.array([[1.6, 1.0, 0.5]]), time_step="0.01"
        ),
        "got time_step = '0.01', gain = ",
    ),
    *[
        (
            f"bound grids {grids!r}",
            lambda r, grids=grids: global_optimum(r, _segment(r), grids=grids),
            "grids must be strictly increasing whole interval counts within [3, 1,000]",
        )
        for grids in [(10**7,), (4.5,), 24, (32, 16)]
    ],
    (
        "inverse kinematics from too many seeds",
        lambda r: inverse_kinematics(r, np.array([3.5, -0.5]), ["x3"], [[0.8]], seeds=10**8),
        "seeds must be a whole number within [1, 1000]; got 100000000",
    ),
    (
        "return map of no samples",
        lambda r: return_map(r, _cycle(r), VELOCITY.resolver, count=0),
        "count must be a whole number within [2, 10,000]; got 0",
    ),
    (
        "return map of text",
        lambda r: return_map(r, _cycle(r), VELOCITY.resolver, values=["a"]),
        "values must be finite strokes of x3, one per sample, shape (k,); got ['a']",
    ),
    (
        "load_robot mass nan",
        lambda r: _crane_with('<mass value="80"/>', '<mass value="nan"/>'),
        """crane.urdf: link 'boom1' <mass value="nan"/> must be a number within [0, 1e+06]""",
    ),
    *[
        (
            f"simulate a law {law!r}",
            lambda r, law=law: simulate(r, law, _segment(r), np.array([STATE])),
            f"a law must be a Resolver (an objective's .resolver, MinVelocityNorm(), a subclass "
            f"of your own); got {law!r}",
        )
        for law in (None, "velocity")
    ],
    (
        "simulate_path a law per segment, one not a law",
        lambda r: redundancy.simulate_path(
            r, [VELOCITY.resolver, None, VELOCITY.resolver], _cycle(r), np.array([STATE])
        ),
        "a law must be a Resolver",
    ),
    (
        "default_start of no segment",
        lambda r: redundancy.default_start(r, None),
        "segment must be a Segment or a Chain",
    ),
    (
        "repeat an unknown strategy",
        lambda r: repeat(r, _cycle(r), VELOCITY.resolver, np.array(STATE), 1, "bogus"),
        "unknown strategy 'bogus'; strategies: free, periodic",
    ),
    (
        "run_study an unknown objective's name",
        lambda r: redundancy.run_study(r, _cycle(r), "speed", progress=False, cycles=0),
        "unknown objective 'speed'; objectives: velocity, energy",
    ),
    (
        "load_robot inertia not a body's",
        lambda r: _crane_with('iyy="17.0666666666667"', 'iyy="-17"'),
        """iyy="-17" iyz="0" izz="17.0666666666667"/> is not a body's rotational inertia""",
    ),
]


class _Overflowing(Resolver):
    """A law of one's own whose null-space term overflows the step."""

    name = "overflowing"

    def null_space(self, space):
        return np.full(space.x.shape, 1e308)


def _crane_with(old, new):
    """``load_robot`` of the crane's URDF with ``old`` replaced by ``new``."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "crane.urdf"
        path.write_text(URDF.replace(old, new, 1))
        return load_robot(path)


def _cycle(robot):
    return WorkCycle.from_toml(robot.task_file, dimension=robot.m)


def _segment(robot):
    return _cycle(robot)["1-2"]


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize(("call", "fragment"), [c[1:] for c in API], ids=[c[0] for c in API])
def test_bad_api_input_is_a_redundancy_error(crane, call, fragment):
    with pytest.raises(RedundancyError) as caught:
        call(crane)
    assert fragment in str(caught.value) and "\n" not in str(caught.value)


def test_the_catalogue_is_large():
    assert len(CASES) + len(API) >= 150
