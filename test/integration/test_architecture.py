"""The import contract (.importlinter, docs/architecture.md) holds, and it is no decoration: a
deliberate import back up a floor, or a circle, breaks it.

The contract is checked by import-linter, as `make test` runs it; these tests run it on the
package's own sources (src/, not the devel space, which holds only the generated msg and srv).
"""
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def lint_imports(src: Path, config: Path = ROOT / ".importlinter") -> subprocess.CompletedProcess:
    """import-linter on the package under ``src`` (which goes first on the path)."""
    code = ("import sys; from importlinter.cli import lint_imports_command; "
            "sys.exit(lint_imports_command())")
    return subprocess.run([sys.executable, "-c", code, "--config", str(config), "--no-cache",
                           "--no-logo"], capture_output=True, text=True, cwd=src.parent,
                          env={"PYTHONPATH": str(src), "PATH": "/usr/bin:/bin"})


def copy_of_the_package(tmp_path: Path) -> Path:
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "ros_hrc", src / "ros_hrc",
                    ignore=shutil.ignore_patterns("__pycache__"))
    return src


def add_line(path: Path, line: str) -> None:
    path.write_text(path.read_text() + "\n" + line + "\n")


def broken_by(tmp_path: Path, module: str, line: str) -> str:
    """import-linter's report on a copy of the package with ``line`` added to ``module`` (a
    path under ros_hrc/), which must break the contract."""
    src = copy_of_the_package(tmp_path)
    add_line(src / "ros_hrc" / module, line)
    done = lint_imports(src)
    assert done.returncode == 1
    return done.stdout


def test_the_package_keeps_its_import_contract():
    done = lint_imports(ROOT / "src")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "BROKEN" not in done.stdout
    assert "4 kept, 0 broken" in done.stdout


def test_an_import_back_up_a_floor_breaks_the_contract(tmp_path):
    # The POMDP toolkit (floor 1) reaching up for the loop's coordinator (floor 6).
    report = broken_by(tmp_path, "pomdp/model.py",
                       "from ros_hrc.loop import coordinator  # noqa: E402")
    assert "The floors of ros_hrc read top-down BROKEN" in report
    assert "ros_hrc.pomdp.model -> ros_hrc.loop.coordinator" in report


def test_a_lazy_import_back_up_breaks_it_too(tmp_path):
    # An import inside a function is an arrow all the same (settings once took the baseline
    # robots' table this way).
    report = broken_by(tmp_path, "settings.py",
                       "def _robots():\n    from ros_hrc.agents import robots\n    return robots")
    assert "ros_hrc.settings -> ros_hrc.agents.robots" in report


def test_a_circle_between_modules_of_one_room_breaks_it(tmp_path):
    report = broken_by(tmp_path, "tasks/definition.py",
                       "def _seed():\n    from ros_hrc.tasks import seed\n    return seed")
    assert "No circle of imports between the modules of one room BROKEN" in report
    assert "No cycles are allowed in ros_hrc.tasks" in report


def test_a_room_on_no_floor_breaks_it(tmp_path):
    src = copy_of_the_package(tmp_path)
    (src / "ros_hrc" / "helpers.py").write_text('"""A module no floor names."""\n')
    done = lint_imports(src)
    assert done.returncode == 1
    assert "ros_hrc.helpers" in done.stdout


def test_ros_outside_the_nodes_breaks_it(tmp_path):
    report = broken_by(tmp_path, "loop/display.py", "import rospy  # noqa: E402")
    assert "Only the nodes import ROS (DESIGN §8) BROKEN" in report


def test_the_architecture_page_shows_todays_room_imports():
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "room_imports.py"), "--check"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
