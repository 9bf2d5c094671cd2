"""The bad-input catalogue thrown at the command line: how many cases hold.

A case holds when the command ends with the right exit status (2), in exactly one line on stderr
(notes aside) that names what it must (and quotes nothing it must not), without a traceback or an
"internal error", and leaves the folder it ran in as it was. The cases are those of
tests/test_bad_input.py, and the classes of machines at their edges: cylinders on or near their
joint's axis, meshes that are no meshes, system files loaded by a xacro or named by a CSV task,
held actuators that cannot be held, and schedulers that never answer.

    python benchmarks/bad_input_catalogue.py [-v]

It runs the command in this process (`redundancy.cli.main`), so the interpreter's `redundancy`
is the one measured: run it with another checkout's interpreter to measure that one.
"""

from __future__ import annotations

import contextlib
import io
import socket
import sys
import tempfile
import threading
from pathlib import Path

TESTS = Path(__file__).parents[1] / "tests"
sys.path.insert(0, str(TESTS))

from test_bad_input import CASES  # noqa: E402

from redundancy.cli import main  # noqa: E402

CRANE = Path(__file__).parents[1] / "redundancy" / "robots" / "hiab031"
INTAKE = TESTS / "fixtures" / "intake"
SECRET = "root:x:0:0:root:/root:/bin/bash\nnobody:x:65534:65534:the-rest-of-the-secret-line\n"
ROD = '<attachment link="boom1" xyz="0.369583691280232 0 -0.0691657078303828"/>'


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"/"
        for p in sorted(folder.rglob("*"))
    }


def _silent_server() -> str:
    """A local TCP server that accepts every connection and never answers."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    _KEPT.append(server)
    threading.Thread(target=lambda: _KEPT.extend(iter(server.accept, None)), daemon=True).start()
    return f"tcp://127.0.0.1:{server.getsockname()[1]}"


def _blackhole() -> str:
    """A local port that drops every new connection, as a blackholed address does: a server
    that never accepts, its queue of connections already full. (An unroutable address is no
    blackhole on every network: a proxy may answer it.)"""
    server = socket.create_server(("127.0.0.1", 0), backlog=0)
    for client in (socket.socket() for _ in range(2)):
        client.setblocking(False)
        client.connect_ex(server.getsockname())
        _KEPT.append(client)
    _KEPT.append(server)
    return f"tcp://127.0.0.1:{server.getsockname()[1]}"


_KEPT: list[socket.socket] = []  # the servers' sockets, open while the catalogue runs


def edge_cases() -> list[tuple[str, list[str], dict, str, str]]:
    """(name, argv, files, fragment the line must hold, text it must not quote)."""
    crane = (CRANE / "hiab031.urdf").read_text()
    crane_toml = (CRANE / "robot.toml").read_text().replace("hiab031.urdf", "c.urdf")
    cases = [
        (
            f"cylinder rod {d} m off its axis",
            ["describe", "--robot", "r.toml"],
            {"c.urdf": crane.replace(ROD, f'<attachment link="boom1" xyz="{d} 0 0"/>')}
            | {"r.toml": crane_toml},
            "cannot move boom1_joint",
            "",
        )
        for d in ("0", "1e-9", "1e-6", "1e-4", "1e-3")
    ]
    arm = (INTAKE / "continuous" / "arm.urdf").read_text()
    sidecar = (INTAKE / "continuous" / "robot.toml").read_text().replace("../task.toml", "t.toml")
    undeclared = (
        sidecar[: sidecar.index("[actuators.x2]")] + sidecar[sidecar.index("[actuators.x3]") :]
    )
    task = (
        'name = "t"\nspeed = 0.5\nsegments = ["1-2"]\nheld = {held}\n[points]\n1 = {a}\n2 = {b}\n'
    )
    cases += [
        (
            "held continuous joint without a stroke",
            ["study", "--robot", "r.toml", "--quiet", "--out", "o"],
            {"arm.urdf": arm, "r.toml": undeclared}
            | {"t.toml": task.format(held='["stick_joint"]', a="[2.8, -0.2]", b="[2.8, 1.2]")},
            "[actuators.stick_joint]",
            "",
        ),
        (
            "held continuous joint without a stroke, check",
            ["check", "--robot", "r.toml"],
            {"arm.urdf": arm, "r.toml": undeclared}
            | {"t.toml": task.format(held='["stick_joint"]', a="[2.8, -0.2]", b="[2.8, 1.2]")},
            "",  # check reports on stdout, exit 2, and no error line
            "",
        ),
        (
            "undeclared joints left free",
            ["study", "--robot", "r.toml", "--quiet", "--out", "o"],
            {"arm.urdf": arm, "r.toml": undeclared.replace('"xz"', '"x"')}
            | {"t.toml": task.format(held='["x3"]', a="[2.8]", b="[2.6]")},
            "locked_joints",
            "",
        ),
        (
            "CSV task naming a system file",
            ["study", "--task", "t.toml", "--quiet"],
            {"passwd": SECRET, "t.toml": 'segments = [{ csv = "passwd" }]\n'},
            "passwd line",
            "rest-of-the-secret",
        ),
        (
            "xacro loading a system file",
            ["describe", "--robot", "a.urdf.xacro"],
            {
                "loaded.yaml": SECRET,
                "a.urdf.xacro": '<robot name="a" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                '<xacro:property name="p" value="${xacro.load_yaml(\'loaded.yaml\')}" '
                'lazy_eval="false"/><link name="base"/><link name="${p}"/></robot>\n',
            },
            "a.urdf.xacro",
            "rest-of-the-secret",
        ),
    ]
    meshes = {p.name: p.read_bytes() for p in (INTAKE / "meshes").iterdir()}
    meshes["t.toml"] = (INTAKE / "task.toml").read_bytes()
    meshes["robot.toml"] = meshes["robot.toml"].replace(b"../task.toml", b"t.toml")
    for name, content in (("garbage", bytes(range(256)) * 12), ("a system file", SECRET.encode())):
        broken = dict(meshes)
        broken |= {m: content for m in ("arm_description/meshes/boom.stl", "meshes/stick.dae")}
        cases.append(
            (
                f"mesh that is {name}",
                ["play", "--robot", "robot.toml", "--html", "p.html"],
                broken,
                "cannot load its visual geometry",
                "rest-of-the-secret",
            )
        )
    for name, address in (
        ("scheduler that accepts and never answers", _silent_server()),
        ("blackholed scheduler address", _blackhole()),
    ):
        cases.append(
            (
                name,
                ["map", "m.toml", "--scheduler", address, "--timeout", "2"],
                {"m.toml": "[task]\n"},
                "no Dask scheduler answered",
                "",
            )
        )
    return cases


def holds(argv: list[str], files: dict, fragment: str, secret: str) -> tuple[bool, str]:
    """Run ``redundancy ARGV`` in a fresh folder holding ``files``: whether the case holds, and
    what stderr said."""
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        for name, content in files.items():
            path = root / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(content if isinstance(content, bytes) else content.encode())
        before = _files(root)
        # text streams over bytes, as a terminal's are (the command reconfigures them)
        err, out = (io.TextIOWrapper(io.BytesIO(), encoding="utf-8") for _ in range(2))
        with (
            contextlib.chdir(root),
            contextlib.redirect_stderr(err),
            contextlib.redirect_stdout(out),
        ):
            try:
                status = main(
                    [*argv, "--quiet"] if argv[0] == "study" and "--quiet" not in argv else argv
                )
            except SystemExit as exit:
                status = exit.code
            except BaseException as error:  # the catalogue counts it, and goes on
                status = f"raised {type(error).__name__}"
        err.flush()
        text = err.buffer.getvalue().decode()  # type: ignore[attr-defined]
        lines = [line for line in text.splitlines() if not line.startswith("redundancy: note:")]
        said = "\n".join(lines)
        if argv[0] == "check" and not fragment:  # reports on stdout, with no error line
            ok = status == 2 and not lines
        else:
            ok = status == 2 and len(lines) == 1 and fragment in lines[0]
            ok = ok and "internal error" not in said and "Traceback" not in said
        ok = ok and (not secret or secret not in said) and _files(root) == before
        return ok, f"exit {status}: {said[:300]}"


def run(verbose: bool = False) -> tuple[int, int]:
    cases = [(c[0], c[1], c[2], c[3], "") for c in CASES] + edge_cases()
    held = 0
    for name, argv, files, fragment, secret in cases:
        ok, said = holds(argv, files, fragment, secret)
        held += ok
        if verbose or not ok:
            print(f"{'holds' if ok else 'FAILS'}: {name}: {said}")
    return held, len(cases)


if __name__ == "__main__":
    import redundancy

    held, total = run("-v" in sys.argv)
    where = Path(redundancy.__file__).parent
    print(f"{held} of {total} hold ({100 * held / total:.1f} %), redundancy at {where}")
