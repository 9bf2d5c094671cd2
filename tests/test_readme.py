"""Every Python block of the README runs, and every number a ``print(...)  # ...`` comment
promises is what the print shows, to the digits the comment gives."""

import ast
import contextlib
import io
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
NUMBER = re.compile(r"-?\d+\.?\d*(?:e-?\d+)?")


def promised(comment: str) -> list[str]:
    """The numbers a comment promises, as written; none when it only describes."""
    return NUMBER.findall(comment) if re.fullmatch(r"[\s\d.,()\[\]e-]+", comment) else []


def shown(output: str, digits: list[str]) -> list[float]:
    """The printed numbers, each rounded to as many decimals as its promised counterpart."""
    values = [float(v) for v in NUMBER.findall(output)]
    assert len(values) == len(digits), (output, digits)
    return [round(v, len(d.split(".")[1]) if "." in d else 0) for v, d in zip(values, digits)]


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize("block", BLOCKS, ids=[f"block{i}" for i in range(len(BLOCKS))])
def test_a_readme_block_runs_and_prints_what_it_promises(block):
    lines = block.splitlines()
    namespace: dict = {}
    for statement in ast.parse(block).body:
        output = io.StringIO()
        with contextlib.redirect_stdout(output):
            exec(compile(ast.Module([statement], []), "README", "exec"), namespace)
        last = lines[statement.end_lineno - 1]
        if "#" in last and isinstance(statement, ast.Expr):
            digits = promised(last.split("#", 1)[1])
            if digits:
                assert shown(output.getvalue(), digits) == [float(d) for d in digits]
