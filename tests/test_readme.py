"""Every Python block of the README and of the pages in docs/ runs, and every number a
``print(...)  # ...`` comment promises is what the print shows, to the digits the comment gives."""

import ast
import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), re.S)


# each distinct block once, named after the first page that shows it
BLOCKS = {block: f"{page.stem}{i}" for page in PAGES[::-1] for i, block in enumerate(blocks(page))}
NUMBER = re.compile(r"-?\d+\.?\d*(?:e-?\d+)?")


def promised(comment: str) -> list[str]:
    """The numbers a comment promises, as written; none when it only describes."""
    return NUMBER.findall(comment) if re.fullmatch(r"[\s\d.,()\[\]e-]+", comment) else []


def shown(output: str, digits: list[str]) -> list[float]:
    """The printed numbers, each rounded to as many decimals as its promised counterpart."""
    values = [float(v) for v in NUMBER.findall(output)]
    assert len(values) == len(digits), (output, digits)
    return [round(v, len(d.split(".")[1]) if "." in d else 0) for v, d in zip(values, digits)]


def test_the_readme_and_the_api_page_have_python_blocks():
    assert blocks(ROOT / "README.md")
    assert len(blocks(ROOT / "docs" / "api.md")) >= 2


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize("block", BLOCKS, ids=BLOCKS.values())
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
