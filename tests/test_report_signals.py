"""``gonio report`` leaves no ``gonio-report-*`` folder in the temporary folder when it is
killed (SIGTERM, SIGINT) or fails (issue 32, item 4).

The report is run as a child process with its own ``TMPDIR`` (so only its folders are
seen there); once its scratch folder exists the signal is sent. The wait for the folder
has a generous deadline only so that a broken run cannot hang the suite: nothing here
asserts a duration.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bad_inputs import run

ROOT = Path(__file__).resolve().parent.parent

#: Longest wait for the child's scratch folder to appear (it takes ~1 s after start; a
#: slow shared machine may take far longer, and the test only needs a bound).
APPEAR_DEADLINE_S = 120.0


def _scratch(tmpdir: Path) -> list[Path]:
    return sorted(tmpdir.glob("gonio-report-*"))


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_killed_report_removes_its_temporary_folder(tmp_path, signum, code):
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    out = tmp_path / "report"
    env = dict(os.environ, TMPDIR=str(tmpdir),
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                        os.environ.get("PYTHONPATH")])))
    # the fit section under --quick runs for several seconds: time enough to be stopped
    child = subprocess.Popen([sys.executable, "-m", "gonio_cli", "report", "--quick",
                              "--sections", "fit", "-o", str(out)], env=env, cwd=tmp_path,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + APPEAR_DEADLINE_S
        while not _scratch(tmpdir) and child.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert _scratch(tmpdir), "the report's scratch folder never appeared"
        assert child.poll() is None, "the report ended before it could be stopped"
        child.send_signal(signum)
        _, err = child.communicate(timeout=APPEAR_DEADLINE_S)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == code, err
    assert _scratch(tmpdir) == [], "the scratch folder was left behind"
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name != "tmp"] == []  # no staged -o
    assert err.strip().splitlines()[-1] == "gonio: " + (
        "terminated" if signum == signal.SIGTERM else "interrupted") + "; nothing was written"
    assert "Traceback" not in err


def test_a_failing_report_removes_its_temporary_folder(tmp_path, monkeypatch):
    """An input that is not JSON is refused inside the report's run, after its scratch
    folder was made: one line, exit 2, and the folder is gone."""
    import tempfile

    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmpdir))
    made, mkdtemp = [], tempfile.mkdtemp
    monkeypatch.setattr(tempfile, "mkdtemp",
                        lambda *a, **k: made.append(mkdtemp(*a, **k)) or made[-1])
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema": "gonio.measurement"')
    code, err = run("report", bad, "--quick", "--sections", "table1", "-o",
                    tmp_path / "report")
    assert code == 2 and err.startswith(f"gonio: error: {bad}: "), err
    assert any(Path(p).name.startswith("gonio-report-") for p in made)  # it was made
    assert _scratch(tmpdir) == []
    assert not (tmp_path / "report").exists()
