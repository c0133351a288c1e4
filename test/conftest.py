"""Fixtures shared by the tests of every folder (test/unit, test/nodes, test/integration)."""
import os

# OpenBLAS's own threads, one per core, spin between products: beside the other pytest worker
# and the launched tests they take the cores the work needs (the solve of
# robot_considerate_fitted.pomdp took 58 s of CPU with them, 15 s without, under load). One
# thread in the tests and every process they start (set before numpy is first imported;
# tools/run_tests.sh sets it too, for the launched tests).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from typing import Iterator  # noqa: E402

import pytest  # noqa: E402

from ros_hrc.link.token import mint_token, read_token  # noqa: E402
from ros_hrc.world import World, WorldConfig  # noqa: E402


@pytest.fixture
def link_token(tmp_path):
    """(token, its file): a launch's link token, made as hrc_check makes it, in a ROS_HOME of
    the test's own."""
    path = mint_token("unit_test", environ={"ROS_HOME": str(tmp_path / "ros_home")})
    return read_token(path), path


@pytest.fixture
def library_without_model(tmp_path):
    """fabric's library in a folder of its own, without a selector model beside it (the
    shipped one is beside models/fabric/library.toml): its manifest's path."""
    from pathlib import Path
    manifest = Path(__file__).resolve().parents[1] / "models" / "fabric" / "library.toml"
    folder = tmp_path / "library"
    folder.mkdir()
    (folder / "library.toml").write_text(
        manifest.read_text().replace('model = "', f'model = "{manifest.parent}/'))
    return folder / "library.toml"


# -- the world's tests: small, headless worlds, closed after each test ---------------------

@pytest.fixture
def world() -> Iterator[World]:
    """The default scene, headless, belt at its default speed."""
    with World(WorldConfig(seed=3)) as w:
        yield w


@pytest.fixture
def still_world() -> Iterator[World]:
    """The default scene with the belt stopped, so the object stays where it is put."""
    with World(WorldConfig(seed=3, belt_speed=0.0)) as w:
        yield w


# -- the order the tests are handed out in ------------------------------------------------

#: The modules whose tests take longest, the longest first (tools/run_tests.sh's
#: ``--durations`` lines show them; docs/performance.md, "Tests in six minutes"). pytest-xdist
#: hands the tests out in collection order (``--no-loadscope-reorder``), so these start
#: first, on both workers, and the many short tests fill in after them: no long test is left
#: to start alone at the end while the other worker idles. A module not listed keeps its
#: place after these.
LONGEST_FIRST = (
    "test/integration/experiment/test_cluster.py",
    "test/integration/experiment/test_warm_stacks.py",
    "test/integration/experiment/test_full_disk.py",
    "test/integration/experiment/test_grid_stacks.py",
    "test/integration/test_extending.py",
    "test/unit/pomdp/test_solver_values_pinned.py",
    "test/integration/test_rooms.py",
    "test/integration/loop/test_terminal_output.py",
    "test/integration/loop/test_startup_ros.py",
    "test/unit/loop/test_fabric_loop.py",
    "test/integration/pomdp/test_hostile_memory_cli.py",
    "test/integration/world/test_world_overlay.py",
    "test/unit/pomdp/test_policy_table.py",
    "test/integration/loop/test_manual_input_human.py",
    "test/integration/loop/test_launch_refuses.py",
)


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """The longest first (:data:`LONGEST_FIRST`), then the groups of pytest-xdist.

    ``--dist loadgroup`` sends the tests of one ``xdist_group`` to one worker by the suffix
    ``@<group>`` that pytest-xdist adds to their node ids in each worker. pytest-xdist 3.8.0
    sets ``item._nodeid``, which pytest 9 no longer reads (a node's id is ``item._id``): no
    test was grouped, and the Ray tests met each other's cluster on their loopback address
    and ports. The suffix is added here wherever xdist's did not take."""
    rank = {module: n for n, module in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
    if not getattr(config.option, "loadgroup", False):   # set in a loadgroup worker only
        return
    from _pytest.nodeid import NodeId   # pytest 9
    for item in items:
        names = sorted({str(mark.args[0] if mark.args else mark.kwargs.get("name", "default"))
                        for mark in item.iter_markers("xdist_group")})
        if names and "@" not in item.nodeid.rpartition("]")[2]:
            item._id = NodeId.parse(f"{item.nodeid}@{'_'.join(names)}")
