"""The examples run headless and print what they promise."""

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_hold_still_example_prints_m_h_and_forces():
    run = subprocess.run(
        [sys.executable, str(EXAMPLES / "hold_still.py")], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    assert "M_H (kg)" in run.stdout
    assert [line.split(":")[0] for line in run.stdout.splitlines()[-3:]] == ["x1", "x2", "x3"]
