"""The catkin package is well-formed: catkin_lint is clean, scripts are installed thin shims."""
import os
import re
import shutil
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_catkin_lint_reports_no_problems():
    assert shutil.which("catkin_lint"), "catkin_lint missing: tools/setup.sh installs catkin-lint"
    # catkin_lint wants the directory named like the package: the workspace link is.
    package_dir = REPO / ".ws" / "src" / "ros_hrc"
    if not package_dir.exists():
        package_dir = REPO
    out = subprocess.run(["catkin_lint", "--strict", "-W2", str(package_dir)],
                         capture_output=True, text=True, env={**os.environ, "LC_ALL": "C.UTF-8"})
    assert "found 0 problems" in out.stderr + out.stdout, out.stdout + out.stderr


def test_every_script_is_a_thin_installed_shim():
    cmake = (REPO / "CMakeLists.txt").read_text()
    for script in sorted((REPO / "scripts").iterdir()):
        assert os.access(script, os.X_OK), f"{script.name} is not executable"
        assert f"scripts/{script.name}" in cmake, f"{script.name} not in catkin_install_python"
        code = [line for line in script.read_text().splitlines()
                if line.strip() and not line.startswith("#")]
        assert len(code) <= 3, f"{script.name} holds logic; move it into src/ros_hrc"
        assert re.match(r"from ros_hrc\.[\w.]+ import main$", code[0])


def test_the_test_runner_lets_a_failing_rostest_fail_the_run():
    # `rostest --text` exits 0 even when its tests fail: CI would stay green on a broken loop.
    runner = (REPO / "tools" / "run_tests.sh").read_text()
    calls = [line for line in runner.splitlines()
             if re.search(r"\brostest\b", line) and not line.lstrip().startswith(("#", "echo"))]
    assert calls, "tools/run_tests.sh runs no rostest"
    for line in calls:
        assert "--text" not in line, line


def test_every_python_package_is_installed_by_setup_py():
    setup = (REPO / "setup.py").read_text()
    for init in sorted((REPO / "src").rglob("__init__.py")):
        package = ".".join(init.parent.relative_to(REPO / "src").parts)
        assert f"'{package}'" in setup, f"{package} is missing from setup.py's packages"


def test_the_workspace_package_does_not_hold_the_workspace():
    # rosrun searches the package directory with `find -L`: if the workspace were inside it,
    # every executable would be found many times and rosrun would ask which one to run.
    package_dir = REPO / ".ws" / "src" / "ros_hrc"
    if package_dir.exists():
        assert not (package_dir / ".ws").exists()
        assert (package_dir / "package.xml").resolve() == (REPO / "package.xml").resolve()
