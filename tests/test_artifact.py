"""Artifacts (envelope, provenance, atomic writes), errors and the Measurement schema."""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

import gonio_cli
from gonio_cli import artifact
from gonio_cli.errors import EXIT_USAGE, ArtifactError, FitError, GonioError, InputError
from gonio_cli.schemas import Measurement, read_measurement, write_measurement

SCHEMA = "gonio.test"


def payload(rng):
    return {
        "wavelength_nm": np.arange(380.0, 790.0, 10.0),
        "brdf_per_sr": rng.uniform(0.0, 3.0, (3, 41)),
        "label": "red ink",
        "converged": np.bool_(True),
        "n_iterations": np.int64(17),
        "nested": {"alpha": np.float32(0.19), "list": (1, 2.5)},
    }


def write_input(folder: Path, rng, n_bytes=(1 << 20) * 2 + 12345) -> Path:
    """An input file larger than sha256_file's 1 MiB block, so several blocks are hashed."""
    path = folder / "red.csv"
    path.write_bytes(rng.integers(0, 256, n_bytes, dtype=np.uint8).tobytes())
    return path


def folder_listing(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


# -------------------------------------------------------------------- round trip --

def test_write_then_read_round_trips_the_payload(tmp_path, rng):
    p = payload(rng)
    out = tmp_path / "a.json"
    written = artifact.write_artifact(out, SCHEMA, 1, p)
    doc = artifact.read_artifact(out, SCHEMA, (1,))
    assert doc == written
    np.testing.assert_array_equal(doc["wavelength_nm"], p["wavelength_nm"])
    np.testing.assert_array_equal(doc["brdf_per_sr"], p["brdf_per_sr"])  # repr is exact
    assert doc["label"] == "red ink" and doc["converged"] is True and doc["n_iterations"] == 17
    assert doc["nested"] == {"alpha": float(np.float32(0.19)), "list": [1, 2.5]}


def test_provenance_fields(tmp_path, rng):
    """The file holds the provenance but no date or duration; those are in its side record
    NAME.run.json (with the file's sha256), and read_artifact puts them back."""
    (tmp_path / "data").mkdir()
    src = write_input(tmp_path / "data", rng)
    out = tmp_path / "out" / "a.json"
    before = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    artifact.write_artifact(out, SCHEMA, 3, {"x": 1, "step": {"time_s": 0.5, "n": 2}},
                            inputs=[src], parameters={"grid_nm": "380:780:10"}, time_s=0.25)
    after = dt.datetime.now(dt.timezone.utc)
    doc = json.loads(out.read_text())
    assert list(doc) == ["schema", "schema_version", "gonio_version", "inputs", "parameters",
                         "x", "step"]
    assert doc["schema"] == SCHEMA and doc["schema_version"] == 3
    assert doc["gonio_version"] == gonio_cli.__version__
    # the input's path from the artifact's folder: out/ → ../data/
    assert doc["inputs"] == [{"path": "../data/" + src.name,
                              "sha256": hashlib.sha256(src.read_bytes()).hexdigest()}]
    assert doc["parameters"] == {"grid_nm": "380:780:10"} and doc["step"] == {"n": 2}
    side = json.loads((tmp_path / "out" / "a.run.json").read_text())
    assert side["schema"] == "gonio.run" and side["artifact"] == "a.json"
    assert side["artifact_sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    assert side["timings"] == {"time_s": 0.25, "step": {"time_s": 0.5}}
    assert side["host"] and side["pid"] == os.getpid()
    created = dt.datetime.strptime(side["created_utc"], "%Y-%m-%dT%H:%M:%SZ")
    assert before <= created.replace(tzinfo=dt.timezone.utc) <= after
    back = artifact.read_artifact(out, SCHEMA, (3,))
    assert back["time_s"] == 0.25 and back["step"] == {"time_s": 0.5, "n": 2}
    assert back["created_utc"] == side["created_utc"]
    # a side record of other bytes is not merged: the times are not this file's
    out.write_text(out.read_text().replace('"x": 1', '"x": 2'))
    back = artifact.read_artifact(out, SCHEMA, (3,))
    assert "time_s" not in back and back["step"] == {"n": 2} and back["x"] == 2


def test_payload_may_not_shadow_the_envelope():
    with pytest.raises(ValueError, match="time_s"):
        artifact.make_document(SCHEMA, 1, {"time_s": 3.0})


# --------------------------------------------------------------------- atomicity --

class Boom(Exception):
    pass


@pytest.mark.parametrize("exc_type", [Boom, KeyboardInterrupt])
def test_failed_write_keeps_the_old_file_and_leaves_no_temp(tmp_path, exc_type):
    out = tmp_path / "a.json"
    out.write_text("old")
    with pytest.raises(exc_type):
        with artifact.atomic_path(out) as tmp:
            assert tmp.parent == out.parent  # same folder, so os.replace is atomic
            tmp.write_text("half-writ")
            raise exc_type()
    assert out.read_text() == "old"
    assert folder_listing(tmp_path) == ["a.json"]


def test_successful_atomic_write_replaces_and_leaves_no_temp(tmp_path):
    out = tmp_path / "sub" / "a.json"  # the folder is created
    with artifact.atomic_path(out) as tmp:
        tmp.write_text("new")
        assert not out.exists()  # nothing visible before success
    assert out.read_text() == "new"
    assert folder_listing(out.parent) == ["a.json"]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_payload_is_refused_and_nothing_is_written(tmp_path, bad):
    out = tmp_path / "a.json"
    out.write_text("old")
    with pytest.raises(ValueError):
        artifact.write_artifact(out, SCHEMA, 1, {"brdf_per_sr": np.array([1.0, bad])})
    assert out.read_text() == "old"
    assert folder_listing(tmp_path) == ["a.json"]


# ----------------------------------------------------------------------- reading --

def _write(text):
    return lambda p: p.write_text(text)


BAD_FILES = {
    "missing": lambda p: None,
    "invalid-json": _write('{"schema": "gonio.test", '),
    "not-an-object": _write("[1, 2, 3]"),
    "no-schema": _write('{"schema_version": 1}'),
    "other-schema": _write('{"schema": "gonio.material", "schema_version": 1}'),
    "unknown-version": _write('{"schema": "gonio.test", "schema_version": 99}'),
    "no-version": _write('{"schema": "gonio.test"}'),
    "not-utf8": lambda p: p.write_bytes(b'{"schema": "\xff\xfe"}'),
    "a-folder": lambda p: p.mkdir(),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_unreadable_artifacts_raise_artifact_error_naming_the_file(tmp_path, case):
    path = tmp_path / f"{case}.json"
    BAD_FILES[case](path)
    with pytest.raises(ArtifactError) as exc:
        artifact.read_artifact(path, SCHEMA, (1, 2))
    assert exc.value.path == os.fspath(path)
    assert str(exc.value).startswith(os.fspath(path) + ": ")
    assert "\n" not in str(exc.value)


def test_unknown_version_message_says_what_is_supported(tmp_path):
    path = tmp_path / "a.json"
    BAD_FILES["unknown-version"](path)
    with pytest.raises(ArtifactError, match=r"schema_version 99 .*reads 1, 2"):
        artifact.read_artifact(path, SCHEMA, (1, 2))


def test_check_keys_refuses_unknown_keys_and_lists_the_allowed():
    artifact.check_keys({"fov_deg": 40, "eye": [0, 0, 1]}, ["eye", "fov_deg", "up"])
    with pytest.raises(ArtifactError) as exc:
        artifact.check_keys({"fov_dg": 40, "eye": 1, "upp": 2}, ["eye", "fov_deg", "up"],
                            path="scene.toml", where="[camera].")
    msg = str(exc.value)
    assert msg.startswith("scene.toml: unknown fields [camera].fov_dg, [camera].upp")
    assert msg.endswith("allowed: eye, fov_deg, up")


# --------------------------------------------------------------------------- errors --

@pytest.mark.parametrize("kwargs, expected", [
    ({"path": "spectra.csv", "row": 42, "column": "theta_i_deg",
      "fix": "fix the angle or drop the row"},
     "spectra.csv:42: column theta_i_deg: theta_i_deg=95 is outside [0, 90); "
     "fix the angle or drop the row"),
    ({"path": Path("data") / "spectra.csv"},
     f"{os.fspath(Path('data') / 'spectra.csv')}: theta_i_deg=95 is outside [0, 90)"),
    ({"row": 3}, "row 3: theta_i_deg=95 is outside [0, 90)"),
    ({"column": "theta_i_deg"}, "column theta_i_deg: theta_i_deg=95 is outside [0, 90)"),
    ({}, "theta_i_deg=95 is outside [0, 90)"),
])
def test_gonio_error_format(kwargs, expected):
    err = GonioError("theta_i_deg=95 is outside [0, 90)", **kwargs)
    assert err.format() == expected
    assert str(err) == expected


def test_gonio_error_format_is_always_one_line():
    err = InputError("bad\nvalue\r\n  here", path="a.csv", row=1, fix="do\tthis\nthen that")
    assert err.format() == "a.csv:1: bad value here; do this then that"


def test_every_error_is_a_gonio_error_with_the_usage_exit_status():
    assert all(issubclass(e, GonioError) for e in (InputError, ArtifactError, FitError))
    assert EXIT_USAGE == 2


# ---------------------------------------------------------------------- measurement --

def measurement_doc(rng, n_cfg=4, n_lambda=5, **changes) -> dict:
    doc = artifact.make_document(Measurement.SCHEMA, Measurement.VERSION, {
        "wavelength_nm": np.linspace(400.0, 700.0, n_lambda),
        "theta_i_deg": rng.uniform(0.0, 80.0, n_cfg),
        "theta_o_deg": rng.uniform(-80.0, 80.0, n_cfg),
        "brdf": rng.uniform(0.0, 5.0, (n_cfg, n_lambda)),
        "brdf_std": rng.uniform(0.0, 0.1, (n_cfg, n_lambda)),
        "n_repeats": rng.integers(1, 10, n_cfg),
        "quantity": "ratio-to-white",
        "summary": {"rows_read": 40},
    })
    doc.update(changes)
    return doc


def test_measurement_round_trip(tmp_path, rng):
    doc = measurement_doc(rng)
    m = Measurement.from_document(doc)
    out = tmp_path / "red.measurement.json"
    write_measurement(out, m, parameters={"grid_nm": "400:700:75"}, time_s=0.5)
    back = read_measurement(out)
    for name in ("wavelength_nm", "theta_i_deg", "theta_o_deg", "brdf", "brdf_std",
                 "n_repeats"):
        np.testing.assert_array_equal(getattr(back, name), doc[name], err_msg=name)
    assert back.quantity == "ratio-to-white" and back.summary == {"rows_read": 40}
    assert back.n_configurations == 4


def test_measurement_defaults_when_optional_fields_are_absent(rng):
    doc = measurement_doc(rng, brdf_std=None)
    del doc["n_repeats"], doc["quantity"], doc["summary"]
    m = Measurement.from_document(doc)
    assert m.brdf_std is None and m.quantity == "brdf" and m.summary == {}
    np.testing.assert_array_equal(m.n_repeats, np.ones(4, dtype=int))


BAD_MEASUREMENTS = {
    "theta_o-size": (lambda d: {"theta_o_deg": d["theta_o_deg"][:3]}, "inconsistent shapes"),
    "brdf-columns": (lambda d: {"brdf": [r[:4] for r in d["brdf"]]}, "inconsistent shapes"),
    "brdf-rows": (lambda d: {"brdf": d["brdf"][:3]}, "inconsistent shapes"),
    "std-shape": (lambda d: {"brdf_std": d["brdf_std"][:2]}, "inconsistent shapes"),
    "repeats-size": (lambda d: {"n_repeats": d["n_repeats"][:1]}, "inconsistent shapes"),
    "brdf-nan": (lambda d: {"brdf": [[float("nan")] + r[1:] for r in d["brdf"]]},
                 "'brdf' holds NaN"),
    "theta-inf": (lambda d: {"theta_i_deg": [float("inf")] + d["theta_i_deg"][1:]},
                  "'theta_i_deg' holds NaN or inf"),
    "brdf-1d": (lambda d: {"brdf": d["brdf"][0]}, "'brdf' has 1 dimensions, expected 2"),
    "wavelength-text": (lambda d: {"wavelength_nm": ["red"] * 5}, "not a numeric array"),
    "ragged": (lambda d: {"brdf": [[1.0], [1.0, 2.0]]}, "not a numeric array"),
    "empty": (lambda d: {"theta_i_deg": [], "theta_o_deg": [], "brdf": np.zeros((0, 5)),
                         "brdf_std": None, "n_repeats": []}, "'theta_i_deg' is empty"),
    "unknown-key": (lambda d: {"brdf_per_sr": 1}, "unknown field brdf_per_sr"),
}


@pytest.mark.parametrize("case", sorted(BAD_MEASUREMENTS))
def test_measurement_refuses_bad_documents_naming_the_file(case, rng):
    change, message = BAD_MEASUREMENTS[case]
    doc = measurement_doc(rng)
    doc.update(change(doc))
    with pytest.raises(ArtifactError) as exc:
        Measurement.from_document(doc, path="red.measurement.json")
    assert str(exc.value).startswith("red.measurement.json: ")
    assert message in str(exc.value)


def test_measurement_missing_field_is_named(rng):
    doc = measurement_doc(rng)
    del doc["theta_o_deg"]
    with pytest.raises(ArtifactError, match="missing field 'theta_o_deg'"):
        Measurement.from_document(doc, path="m.json")


@pytest.mark.parametrize("summary", [[1, 2], "rows_read"])
def test_measurement_refuses_a_summary_that_is_not_an_object(summary, rng):
    with pytest.raises(ArtifactError, match="summary"):
        Measurement.from_document(measurement_doc(rng, summary=summary), path="m.json")


def test_read_measurement_refuses_another_schema(tmp_path, rng):
    out = tmp_path / "m.json"
    artifact.write_json(out, {**measurement_doc(rng), "schema": "gonio.material"})
    with pytest.raises(ArtifactError, match="expected 'gonio.measurement'"):
        read_measurement(out)


def test_atomic_writes_get_normal_file_permissions(tmp_path):
    # mkstemp makes 0600 files; an artifact must be readable like any file the user makes.
    import os
    import stat

    from gonio_cli.artifact import atomic_path

    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "a.json") as tmp:
            tmp.write_text("{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.json").stat().st_mode) == 0o644


def test_image_metadata_is_the_envelope_without_a_time(tmp_path):
    """Every image gonio writes carries schema, version, gonio version and its inputs'
    SHA-256 (hashlib of the file's bytes), and no time stamp (same settings, same bytes)."""
    from gonio_cli.imageio import read_image, write_png

    src = tmp_path / "in.csv"
    src.write_bytes(b"a,b\n1,2\n")
    meta = artifact.image_metadata("gonio.test-image", 3, inputs=[src],
                                   parameters={"size": 4}, method="m", weights=np.arange(2.0))
    assert meta == {"schema": "gonio.test-image", "schema_version": 3,
                    "gonio_version": gonio_cli.__version__,
                    "inputs": [{"path": str(src),
                                "sha256": hashlib.sha256(b"a,b\n1,2\n").hexdigest()}],
                    "parameters": {"size": 4}, "method": "m", "weights": [0.0, 1.0]}
    with pytest.raises(ValueError, match="gonio_version"):
        artifact.image_metadata("gonio.test-image", 1, gonio_version="0")
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    pixels = np.zeros((2, 3, 3), np.uint8)
    write_png(a, pixels, meta)
    write_png(b, pixels, meta)
    assert a.read_bytes() == b.read_bytes()
    back = read_image(a).metadata
    assert back["gonio_version"] == gonio_cli.__version__
    # the file records the input's path relative to its own folder (here, the same one)
    assert json.loads(back["inputs"]) == [{**meta["inputs"][0], "path": "in.csv"}]
    assert back["schema_version"] == "3"
    assert a.read_bytes().count(b"gonio:gonio_version") == 1     # written once
