"""`make demo` refuses what it cannot run with exit status 2, before it writes anything."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_demo_without_its_motion_data_names_the_missing_folder_and_exits_2(tmp_path, motion_data):
    var, missing = tmp_path / "var", tmp_path / "no-such-data"
    env = {key: value for key, value in os.environ.items() if key != "DATABASE_URL"}  # the embedded database
    env.update(MOTION_DATA=f"{motion_data}:{missing}", STUDYAPP_VAR_DIR=str(var))
    result = subprocess.run([sys.executable, "-m", "studyapp.demo"], cwd=ROOT, env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2, result.stdout + result.stderr
    assert f"no motion data at {missing}" in result.stdout + result.stderr
    assert not (var / "db.sqlite3").exists()
