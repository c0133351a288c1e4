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


def test_the_package_keeps_its_import_contract():
    done = lint_imports(ROOT / "src")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "BROKEN" not in done.stdout
    assert "4 kept, 0 broken" in done.stdout


#: Five ways to break the contract, one per kind it must catch: (module under ros_hrc/, the line
#: added to it, what import-linter's report must then say).
BREAKAGES = [
    # The POMDP toolkit (floor 3) reaching up for the loop's coordinator (floor 7).
    ("pomdp/model.py", "from ros_hrc.loop import coordinator  # noqa: E402",
     ["The floors of ros_hrc read top-down BROKEN",
      "ros_hrc.pomdp.model -> ros_hrc.loop.coordinator"]),
    # An import inside a function is an arrow all the same (settings once took the baseline
    # robots' table this way).
    ("settings.py", "def _robots():\n    from ros_hrc.agents import robots\n    return robots",
     ["ros_hrc.settings -> ros_hrc.agents.robots"]),
    ("tasks/definition.py", "def _seed():\n    from ros_hrc.tasks import seed\n    return seed",
     ["No circle of imports between the modules of one room BROKEN",
      "No cycles are allowed in ros_hrc.tasks"]),
    ("loop/display.py", "import rospy  # noqa: E402",
     ["Only the nodes import ROS (DESIGN §8) BROKEN"]),
]


def test_each_kind_of_breakage_breaks_the_contract(tmp_path):
    """One copy of the package with every breakage at once, and a room on no floor
    (helpers.py), checked in one run of import-linter: its report names each."""
    src = copy_of_the_package(tmp_path)
    for module, line, _ in BREAKAGES:
        add_line(src / "ros_hrc" / module, line)
    (src / "ros_hrc" / "helpers.py").write_text('"""A module no floor names."""\n')
    done = lint_imports(src)
    assert done.returncode == 1, done.stdout + done.stderr
    for _, _, said in BREAKAGES:
        for text in said:
            assert text in done.stdout, (text, done.stdout)
    assert "ros_hrc.helpers" in done.stdout, done.stdout


def test_the_architecture_page_shows_todays_room_imports():
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "room_imports.py"), "--check"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
