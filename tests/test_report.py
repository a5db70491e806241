"""``gonio report``: the quick report runs once per module and is checked for
every section's table and plot, finite numbers, Table 1 beside the paper, and error and
time in every error-against-time row; bad options write nothing. Timings are not asserted
(STYLE 12): the report measures them, the tests only check that they are there."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gonio_cli import cli, log
from gonio_cli.errors import InputError
from gonio_cli.report import SECTION_NAMES, parse_sections
from gonio_cli.report import scatter as SC
from gonio_cli.report import sheets as SH
from gonio_cli.report import table1 as T1

PLOTS = {"fit": ["fit.png"], "lobes": ["lobes.png"], "prefilter": ["prefilter.png"],
         "render": ["render.png"], "table1": ["table1.png", "table1_spheres.png"]}


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    """One ``gonio report --quick`` into a fresh folder (≈ 20 s on 2 cores)."""
    out = tmp_path_factory.mktemp("report") / "r"
    code = cli.run(["-q", "report", "--quick", "-o", str(out)])
    log.set_quiet(False)
    assert code == 0
    return out, (out / "report.md").read_text(encoding="utf-8"), \
        json.loads((out / "report.json").read_text(encoding="utf-8"))


def _floats(obj):
    if isinstance(obj, float):
        yield obj
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _floats(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _floats(v)


def test_quick_report_has_every_section_table_and_plot(quick_report):
    out, md, doc = quick_report
    assert doc["schema"] == "gonio.report" and doc["schema_version"] == 1
    assert doc["quick"] is True and list(doc["sections"]) == list(SECTION_NAMES)
    for name in SECTION_NAMES:
        assert f'<a id="{name}"></a>' in md
        for plot in PLOTS.get(name, []):
            assert (out / plot).stat().st_size > 1000, plot  # a real PNG, not an empty file
            assert f"({plot})" in md
        assert doc["sections"][name]["time_s"] > 0
    # each section but the sheets has at least one Markdown table after its heading
    for name in PLOTS:
        body = md.split(f'<a id="{name}"></a>')[1].split("<a id=")[0]
        assert "|---" in body, name
    sheets = doc["sections"]["sheets"]["sheets"]
    assert len(sheets) == 6  # three inks × two models
    for s in sheets:
        assert (out / s["file"]).stat().st_size > 1000
    # nothing left behind beside the report folder (the staging folder was moved)
    assert [p.name for p in out.parent.iterdir()] == ["r"]


def test_every_number_is_finite(quick_report):
    _, _, doc = quick_report
    values = list(_floats(doc["sections"]))
    assert len(values) > 100 and all(math.isfinite(v) for v in values)


def test_table1_has_the_papers_numbers_and_ours(quick_report):
    _, md, doc = quick_report
    t1 = doc["sections"]["table1"]
    body = md.split('<a id="table1"></a>')[1]
    for model, per_ink in T1.PAPER_TABLE1.items():
        for ink in ("red", "green", "blue"):
            rmse, ssim = per_ink[ink]
            assert f"{rmse:.4f}" in body and f"{ssim:.4f}" in body
    assert "107 µs" in body and "116 µs" in body
    assert len(t1["rows"]) == 6
    for r in t1["rows"]:
        assert f"{r['rmse']:.4f}" in body and f"{r['ssim']:.4f}" in body
        assert 0 <= r["rmse"] <= 1 and -1 <= r["ssim"] <= 1 and r["frame_ms"] > 0
    assert "Where and why ours differ" in body


def test_error_against_time_rows_have_error_and_time(quick_report):
    _, _, doc = quick_report
    s = doc["sections"]
    pairs = ([(r["log_rmse"], r["time_ms"]) for r in s["fit"]["goniochromatic"]]
             + [(r["relative_rmse_percent"], r["time_ms"]) for r in s["fit"]["comparison"]]
             + [(r["rel_rms_worst"], r["time_ms"]) for r in s["lobes"]["rows"]]
             + [(r["p99_error"], r["ring_s"]) for r in s["prefilter"]["brute"]]
             + [(r["p99_error"], r["time_s"]) for r in s["prefilter"]["ring"]]
             + [(r["de2000_mean"], r["frame_ms"]) for r in s["render"]["rows"]]
             + [(r["rmse"], r["frame_ms"]) for r in s["table1"]["rows"]])
    assert len(pairs) > 30
    for err, t in pairs:
        assert err >= 0 and t > 0


def test_render_sweep_converges_to_its_reference(quick_report):
    # more supersampling and more triangles approach the reference (exact, ssaa 4, 288
    # segments): the error must fall along each sweep, a check that cannot pass by luck
    rows = quick_report[2]["sections"]["render"]["rows"]
    ssaa = [r["de2000_mean"] for r in rows if r["sweep"] == "table, ssaa 1-3"]
    tess = [r["de2000_mean"] for r in rows if r["sweep"].startswith("table, ssaa 2, seg")]
    assert ssaa == sorted(ssaa, reverse=True) and tess == sorted(tess, reverse=True)


def test_bad_sections_exit_2_one_line_nothing_written(run_gonio, tmp_path):
    out = tmp_path / "r"
    res = run_gonio("report", "--quick", "-o", out, "--sections", "fit,tabel1")
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "tabel1" in lines[0] and "table1" in lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_missing_input_file_exit_2(run_gonio, tmp_path):
    res = run_gonio("report", tmp_path / "nope.measurement.json", "-o", tmp_path / "r")
    assert res.exit_code == 2 and "nope.measurement.json" in res.stderr
    assert list(tmp_path.iterdir()) == []


def test_parse_sections_orders_and_refuses():
    assert parse_sections(None) == list(SECTION_NAMES)
    assert parse_sections("table1, fit") == ["fit", "table1"]
    with pytest.raises(InputError, match="valid|use a comma"):
        parse_sections("fitt")


def test_image_errors_closed_forms():
    rng = np.random.default_rng(7)
    a = rng.random((32, 32, 3))
    assert T1.image_errors(a, a) == pytest.approx((0.0, 1.0))
    # a constant offset d gives RMSE exactly d
    assert T1.image_errors(np.clip(a, 0, 0.9) + 0.1, np.clip(a, 0, 0.9))[0] == \
        pytest.approx(0.1)


def test_sheet_colours_grey_lambertian_is_white():
    # a spectrally flat Lambertian under D65 shows D65's colour: sRGB (1, 1, 1) after
    # normalisation, in every direction (IEC matrix maps D65 to equal channels to ~1e-3)
    from gonio_cli.schemas import Material
    from gonio_cli.spectra import parse_grid

    wl = parse_grid()
    flat = np.ones_like(wl)
    grey = Material("cook-torrance", wl, {"kd": 0.5 * flat, "ks": 0 * flat,
                                          "m": 0.3 * flat, "f0": 0 * flat})
    rgb, y = SH.direction_colours(grey, [10.0, 50.0], np.linspace(-80, 80, 9))
    assert rgb.shape == (2, 9, 3) and np.allclose(rgb, 1.0, atol=5e-3)
    assert np.allclose(y, 0.5 / np.pi, rtol=1e-2)  # Y of f = kd/π for a D65-normalised light


def test_sheets_from_a_material_file(run_gonio, tmp_path):
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid
    from gonio_cli.synthetic import ink_spectra

    wl = parse_grid()
    rho, c = ink_spectra("green", wl)
    write_material(tmp_path / "g.material.json",
                   Material("goniochromatic", wl, {"alpha": 0.2, "rho": rho, "c": c}))
    res = run_gonio("report", tmp_path / "g.material.json", "-o", tmp_path / "r",
                    "--sections", "sheets")
    assert res.exit_code == 0, res.stderr
    doc = json.loads((tmp_path / "r/report.json").read_text())
    assert doc["inputs"][0]["path"].endswith("g.material.json")
    (sheet,) = doc["sections"]["sheets"]["sheets"]
    assert sheet["material"] == "g" and (tmp_path / "r" / sheet["file"]).is_file()
    # green ink: the mirror colour at θi = 15° is green-dominant
    r, g, b = sheet["mirror_srgb"][0]
    assert g == pytest.approx(1.0) and g > r and g > b


def test_lobes_section_times_the_environment_render_per_lobe_count(quick_report):
    # "lobes: lobe count: BRDF approximation error, weight-fit time, render time".
    _, _, doc = quick_report
    lobes = doc["sections"]["lobes"]
    counts = [b["lobes"] for b in lobes["basis"]]
    assert [r["lobes"] for r in lobes["render"]] == counts
    assert all(r["render_ms"] > 0 and r["pixels"] > 1000 for r in lobes["render"])


def test_no_time_is_printed_as_zero(quick_report):
    import re

    _, md, _ = quick_report
    # a time rounded to nothing ("0.0 s", "0.000", "| 0.0 |") says the run took no time
    assert not re.search(r"(?<![\d.])0\.0+ ?(s|ms)\b", md)
    head = md.split('<a id="fit"></a>')[0]
    assert re.search(r"\| \[.*\]\(#sheets\) \| (<1 ms|[\d.]+ m?s) \|", head)
    from gonio_cli.report.section import format_seconds

    assert [format_seconds(t) for t in (0.0, 4e-4, 0.0123, 0.5, 2.345, 61.0)] == \
        ["<1 ms", "<1 ms", "12.3 ms", "500 ms", "2.35 s", "61 s"]


def test_plots_say_what_they_show(monkeypatch, tmp_path):
    """The Table 1 plot names each ink's points; the prefilter plot marks errors drawn at
    the 1e-9 floor as exact (in the legend) instead of showing them as measured 1e-9."""
    from matplotlib.figure import Figure

    seen = {}

    def record(fig, path, *args, **kwargs):
        ax = fig.axes[0]
        seen[path] = ([t.get_text() for t in ax.texts],
                      [t.get_text() for t in ax.get_legend().get_texts()])

    monkeypatch.setattr(Figure, "savefig", record)
    SC.scatter(tmp_path / "t1.png", {"eq. 5": ([10, 20], [0.1, 0.2])}, "x", "y", "t",
               point_labels={"eq. 5": ["red ink", "green ink"]})
    assert seen[tmp_path / "t1.png"][0] == ["red ink", "green ink"]
    SC.scatter(tmp_path / "p.png", {"ring": ([0.1, 0.2, 0.3], [0.0, 1e-12, 1e-4])}, "x", "y",
               "t", floor=SC.ERROR_FLOOR)
    legend = seen[tmp_path / "p.png"][1]
    assert legend[0] == "ring" and "≤1e-09 (exact)" in legend[1]
    SC.scatter(tmp_path / "q.png", {"ring": ([0.1], [1e-4])}, "x", "y", "t",
               floor=SC.ERROR_FLOOR)
    assert seen[tmp_path / "q.png"][1] == ["ring"]          # nothing floored: no such entry


def test_scratch_folder_is_private_and_removed(monkeypatch, run_gonio, tmp_path):
    """Scratch files go to a fresh private folder per run (tempfile.mkdtemp), never a
    fixed name: two runs (make -j, two users) cannot collide."""
    import gonio_cli.report as R

    workdirs = []

    def fake_run_report(names, workdir, **kwargs):
        assert workdir.is_dir() and list(workdir.iterdir()) == []
        assert (workdir.stat().st_mode & 0o777) == 0o700
        workdirs.append(workdir)
        return R.Report([], [], True)

    monkeypatch.setattr(R, "run_report", fake_run_report)
    for k in range(2):
        assert run_gonio("report", "-o", tmp_path / f"r{k}", "--sections", "fit").exit_code == 0
    assert workdirs[0] != workdirs[1]
    assert not any(w.exists() for w in workdirs)
