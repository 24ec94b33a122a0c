"""scripts/moglow-fidelity.sh refuses settings it cannot honour before it trains or writes anything."""
import os
import signal
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "moglow-fidelity.sh"


def run_script(out: Path, **settings: str) -> subprocess.CompletedProcess:
    """The script's result; on a timeout its whole process group is killed, so a script that
    wrongly started training leaves no training behind."""
    process = subprocess.Popen(["bash", str(SCRIPT), str(out)], env={**os.environ, **settings},
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        stdout, stderr = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


@pytest.mark.parametrize("settings, message", [
    ({"SYSTEMS": "MoGlow MG-X"}, "unknown system 'MG-X' in SYSTEMS"),
    ({"MOGLOW_STEPS": "20000", "MGD_STEPS": "9000", "MGD_BRANCH": "13000"},
     "MGD_STEPS=9000 must be past MGD_BRANCH=13000"),
    ({"MGD_BRANCH": "abc"}, "MGD_BRANCH must be a whole number, got 'abc'"),
    ({"MGD_BRANCH": "-5"}, "MGD_BRANCH must be a whole number, got '-5'"),
    ({"SAMPLES": "x"}, "SAMPLES must be a whole number, got 'x'"),
    ({"MOGLOW_STEPS": "1e3"}, "MOGLOW_STEPS must be a whole number, got '1e3'"),
    ({"RNN_STEPS": "08"}, "RNN_STEPS must be a whole number, got '08'"),
    ({"THREADS": "0"}, "THREADS and SAMPLES must be at least 1"),
])
def test_refused_settings_exit_2_and_create_nothing(tmp_path, settings, message):
    out = tmp_path / "fidelity"
    result = run_script(out, **settings)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
    assert not out.exists()


@pytest.mark.parametrize("branch, first_step", [
    ({}, "train-MG-D"),                         # the default: MG-D from scratch, nothing before it
    ({"MGD_BRANCH": "13000"}, "train-MoGlow"),  # branched: MoGlow's run to the branch step first
])
def test_a_refused_step_passes_its_exit_status_on_and_names_its_log(tmp_path, branch, first_step):
    """MGD_STEPS short of MOGLOW_STEPS is accepted; the first step then refuses the missing folder."""
    out, missing = tmp_path / "fidelity", tmp_path / "no-such-folder"
    result = run_script(out, MOGLOW_STEPS="20000", MGD_STEPS="18500", DATA=str(missing), SYSTEMS="MG-D",
                        **branch)
    assert result.returncode == 2
    log = out / "logs" / f"{first_step}.log"
    assert f"{first_step} failed; see {log}" in result.stderr
    assert f"motion folder {missing} does not exist" in log.read_text()
