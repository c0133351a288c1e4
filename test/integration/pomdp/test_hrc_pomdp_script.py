"""scripts/hrc_pomdp as a user runs it: the command's exit status is the script's. (The
command's verbs in-process: test/unit/pomdp/test_io.py.)"""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_the_script_exits_with_the_status(tmp_path):
    bad = tmp_path / "bad.pomdp"
    bad.write_text("discount: 2\n")
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "hrc_pomdp"), "info", str(bad)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip() == f"hrc_pomdp: {bad}:1: discount 2 is outside [0, 1)"
