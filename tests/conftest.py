import ast
import functools
import os
import sys
from pathlib import Path

import pytest

# The benchmarks' helpers the tests share: the pink peer, the evaluation counter
sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))

# One BLAS thread a process (and so in the processes the tests start), as scripts/test.sh sets:
# the matrices are small, and idle OpenBLAS threads spin beside the other workers.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

from tqdm import tqdm  # noqa: E402

from redundancy import load_robot  # noqa: E402  (numpy reads the thread count on import)
from redundancy.planning.tasks import WorkCycle  # noqa: E402
from redundancy.study.study import run_study  # noqa: E402

# No progress-bar monitor thread outlives a test: a process running other threads computes a
# `Background` computation in place instead of forking, and tests/test_background.py checks the
# fork itself
tqdm.monitor_interval = 0

# -- on every core: scripts/test.sh runs the suite under pytest-xdist, `--dist loadgroup` ------
#
# Each worker builds its own module and session fixtures. The tests that use one of the
# fixtures below, which take seconds to build, form one unit that one worker runs, so that the
# fixture is built once per run (xdist's own `xdist_group` marks are not used: with pytest 9.2
# and xdist 3.8 they are ignored, pytest-xdist issue #1386). The live playback tests are one
# unit too: each checks that no port its server held is listened on once the server has gone,
# which the server of a live playback test on the other worker could take meanwhile.
TESTS = Path(__file__).parent
SHARED = {
    ("test_study.py", "study"): "paper study",
    ("test_cycles.py", "crane_study"): "paper study",
    ("test_cycles.py", "arm_runs"): "planar arm cycles",
    ("test_hydraulics.py", "motions"): "hydraulic baselines and bounds",
    ("test_hydraulics.py", "bounds"): "hydraulic baselines and bounds",
    ("test_global_optimum.py", "optima"): "global optima",
    ("test_global_optimum.py", "bundled_optima"): "bundled robots' optima",
    ("test_output.py", "earlier"): "earlier output",
    ("test_maps.py", "client"): "dask client",
    ("test_integral_optimum.py", "plain"): "4R integral optima",
    ("test_integral_optimum.py", "steered"): "4R integral optima",
}
# Units that take longest go first (CPU seconds in a 2-worker run, 2026-11-23), so that no
# worker is left with a long one at the end.
LONGEST_FIRST = [
    "4R integral optima",  # 60
    "dask client",  # 13
    "hydraulic baselines and bounds",  # 22
    "tests/test_readme.py::test_a_readme_block_runs_and_prints_what_it_promises[block2]",  # 16
    "earlier output",  # 15
    "tests/test_study.py::test_study_command_writes_the_report_and_the_five_figures",  # 11
    "planar arm cycles",  # 10
    "paper study",  # 9
    "bundled robots' optima",  # 9
    "tests/test_output.py::test_two_runs_into_one_folder_leave_one_complete_output",  # 9
    "live playback",  # 8 (most of it waiting)
    "global optima",  # 6
    "tests/test_maps.py::test_bad_map_runs_get_one_line_and_exit_2",  # 6
    "tests/test_cycles.py::test_the_cycle_command_writes_its_report_figures_and_playback",  # 5
]


@functools.cache
def _parameters(module: str) -> dict[str, set[str]]:
    """The parameters (fixtures) of each test function of a test module."""
    path = TESTS / module
    if not path.is_file():
        return {}
    return {
        node.name: {a.arg for a in node.args.args}
        for node in ast.parse(path.read_text()).body
        if isinstance(node, ast.FunctionDef)
    }


def unit_of(nodeid: str) -> str:
    """The unit of work a test belongs to: its group, or the test alone."""
    path, _, name = nodeid.partition("::")
    module, function = Path(path).name, name.split("[")[0]
    if module == "test_viz.py" and function.startswith("test_live_playback_"):
        return "live playback"
    used = _parameters(module).get(function, set())
    groups = {group for (m, fixture), group in SHARED.items() if m == module and fixture in used}
    return " + ".join(sorted(groups)) or nodeid


@pytest.hookimpl(optionalhook=True)  # an xdist hook: unknown with -p no:xdist
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SharedFixtureScheduling(LoadScopeScheduling):
        """xdist's loadscope with the units of `unit_of`, in the order the workers collect."""

        def _split_scope(self, nodeid: str) -> str:
            return unit_of(nodeid)

    config.option.loadscopereorder = False
    return SharedFixtureScheduling(config, log)


def pytest_collection_modifyitems(items):
    """On an xdist worker, the units of LONGEST_FIRST first, each kept together; the scheduler
    hands units out in this order. A run in one process keeps the files' order."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        return
    rank = {unit: i for i, unit in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(unit_of(item.nodeid), len(rank)))


# -- fixtures --------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def crane():
    return load_robot("hiab031")


@pytest.fixture(scope="session")
def paper_cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


@pytest.fixture(scope="session")
def paper_study(crane, paper_cycle):
    """The paper's study on the crane with a 3-cycle cycle section, shared by test_study and
    test_cycles (whose crane cycle study is its cycle section)."""
    return run_study(crane, paper_cycle, samples=40, progress=False, cycles=3)
