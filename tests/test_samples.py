"""The bundled sample data: found without the source tree's layout, how the demo reads it
said once (sample_data/inks.toml) and read the same by Python and by the Makefile."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from gonio_cli import samples
from gonio_cli.errors import InputError

CHECKOUT = Path(__file__).resolve().parent.parent / "sample_data"


def test_found_in_the_checkout_or_where_the_variable_says(monkeypatch, tmp_path):
    monkeypatch.delenv(samples.SAMPLE_DATA_ENV, raising=False)
    assert samples.sample_data_dir() == CHECKOUT
    (tmp_path / samples.INKS_FILE).write_text('[ink.x]\nfiles = ["x.csv"]\n')
    monkeypatch.setenv(samples.SAMPLE_DATA_ENV, str(tmp_path))
    assert samples.sample_data_dir() == tmp_path
    assert samples.demo_inks() == [samples.DemoInk("x", (tmp_path / "x.csv",), {})]


def test_an_installed_gonio_without_the_data_says_what_to_do(monkeypatch, tmp_path):
    # a package that is not in a checkout: nothing beside it, no variable
    fake = tmp_path / "site-packages" / "gonio_cli" / "samples.py"
    fake.parent.mkdir(parents=True)
    monkeypatch.setattr(samples, "__file__", str(fake))
    monkeypatch.delenv(samples.SAMPLE_DATA_ENV, raising=False)
    with pytest.raises(InputError) as info:
        samples.sample_data_dir()
    assert samples.SAMPLE_DATA_ENV in str(info.value) and "\n" not in str(info.value)
    monkeypatch.setenv(samples.SAMPLE_DATA_ENV, str(tmp_path))     # no inks.toml there
    with pytest.raises(InputError, match="inks.toml"):
        samples.sample_data_dir()


def test_the_demo_inks_are_the_shipped_files_with_their_options():
    inks = {i.name: i for i in samples.demo_inks(CHECKOUT)}
    assert list(inks) == ["red", "green", "blue"]
    assert all(p.is_file() for i in inks.values() for p in i.files)
    # the green ink's file says, in its first line, how it was measured
    first = inks["green"].files[0].read_text(encoding="utf-8-sig").splitlines()[0]
    assert "ratio-to-white (white standard 0.99)" in first
    assert inks["green"].ingest == {"quantity": "ratio-to-white", "white_reflectance": 0.99}
    assert inks["red"].ingest == {} and len(inks["blue"].files) == 2


@pytest.mark.parametrize("args, out", [
    (["ingest-args", "green"], "--quantity ratio-to-white --white-reflectance 0.99"),
    (["ingest-args", "red"], ""),
    (["fit-args"], "--exclude-theta-i-deg 70"),
])
def test_the_makefile_reads_the_same_options(args, out):
    r = subprocess.run([sys.executable, "-m", "gonio_cli.samples", *args],
                       capture_output=True, text=True, timeout=60,
                       env={"GONIO_SAMPLE_DATA": str(CHECKOUT), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == out


def test_an_unknown_ink_is_one_line_exit_2():
    r = subprocess.run([sys.executable, "-m", "gonio_cli.samples", "ingest-args", "cyan"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "red, green, blue" in r.stderr
    assert r.stderr.count("\n") == 1


def test_report_without_the_sample_data_is_one_line_exit_2(run_gonio, monkeypatch, tmp_path):
    monkeypatch.setenv(samples.SAMPLE_DATA_ENV, str(tmp_path / "nowhere"))
    out = tmp_path / "report"
    r = run_gonio("report", "--quick", "--sections", "fit", "-o", out)
    assert r.exit_code == 2 and not out.exists()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and samples.INKS_FILE in lines[0] and "nowhere" in lines[0]
