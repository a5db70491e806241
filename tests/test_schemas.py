"""The one definition per artifact (gonio_cli.schemas): the published JSON Schemas in
docs/schemas/ are what it generates; real artifacts pass them and broken ones fail them
(with the ``jsonschema`` library when it is installed); every model parameter and every
ingest quantity has its range."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from bad_inputs import broken, make_good, set_key

from gonio_cli import schemas
from gonio_cli.brdf import MODELS
from gonio_cli.errors import ArtifactError, GonioError

DOCS = Path(__file__).resolve().parent.parent / "docs" / "schemas"


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def test_published_schemas_are_what_the_definition_generates():
    """docs/schemas/ cannot drift from gonio_cli/schemas/: `make schemas` rewrites it."""
    expected = schemas.schema_files()
    assert sorted(p.name for p in DOCS.glob("*.json")) == sorted(expected)
    for name, text in expected.items():
        assert (DOCS / name).read_text(encoding="utf-8") == text, (
            f"docs/schemas/{name} differs from gonio_cli/schemas/: run make schemas")


def test_every_model_parameter_has_a_range():
    for model in MODELS.values():
        for name in model.scalar_params + model.spectral_params:
            assert name in schemas.PARAM_RANGES, f"{model.name}.{name} has no range"


def test_measurement_quantities_are_ingests():
    from gonio_cli.ingest.quantities import QUANTITIES

    assert set(schemas.Measurement.QUANTITIES) == set(QUANTITIES)


def test_ranges_agree_with_the_stages_own_bounds():
    """The read side accepts everything the writers may produce."""
    from gonio_cli.fit.common import ALPHA_MAX, ALPHA_MIN
    from gonio_cli.fit.separable import C_LIMIT
    from gonio_cli.fit.cook_torrance_profile import M_MAX, M_MIN
    from gonio_cli.prefilter.inputs import MAX_EXPONENT

    alpha, m, c = (schemas.PARAM_RANGES[k] for k in ("alpha", "m", "c"))
    assert not alpha.outside(np.array([ALPHA_MIN, ALPHA_MAX])).any()
    assert not m.outside(np.array([M_MIN, M_MAX])).any()
    assert not c.outside(np.array([-C_LIMIT, C_LIMIT])).any()
    assert schemas.EXPONENT_RANGE == (1.0, MAX_EXPONENT)


# ------------------------------------------------------------ the Python validator --

READERS = {"measurement": schemas.read_measurement, "material": schemas.read_material,
           "basis": schemas.read_lobe_basis, "lobes": schemas.read_lobes,
           "index": schemas.read_prefilter_index, "report": schemas.read_render_report}


@pytest.mark.parametrize("kind", sorted(READERS))
def test_real_artifacts_are_read(good, kind):
    READERS[kind](good[kind])


@pytest.mark.parametrize("kind", sorted(READERS))
def test_an_unknown_field_is_one_line_naming_file_and_field(good, tmp_path, kind):
    bad = broken(good[kind], tmp_path, set_key("typo_field", 1))
    with pytest.raises(ArtifactError) as info:
        READERS[kind](bad)
    text = str(info.value)
    assert text.startswith(f"{bad}: ") and "typo_field" in text and "\n" not in text


@pytest.mark.parametrize("value,message", [
    (3.0, "expected an integer"), ("3", "expected an integer"), (True, "expected an integer"),
    (0, "outside [1, inf]"), (None, "null"),
])
def test_integer_fields_refuse_other_types(good, tmp_path, value, message):
    bad = broken(good["basis"], tmp_path, lambda d: d["bases"][0].__setitem__("n_lobes", value))
    with pytest.raises(ArtifactError, match="'bases\\[0\\].n_lobes'") as info:
        schemas.read_lobe_basis(bad)
    assert message in str(info.value)


def test_render_report_fields_are_checked(good, tmp_path):
    bad = broken(good["report"], tmp_path, set_key("frame_time_s", -1.0))
    with pytest.raises(ArtifactError, match="'frame_time_s' is -1, outside"):
        schemas.read_render_report(bad)


def test_every_message_names_a_fix(good, tmp_path):
    bad = broken(good["lobes"], tmp_path, set_key("n_samples", 4))
    with pytest.raises(GonioError) as info:
        schemas.read_lobes(bad)
    assert info.value.fix == "regenerate it with gonio lobes fit"


# ---------------------------------------------------------------- JSON Schema (users) --

@pytest.fixture(scope="module")
def validators():
    import jsonschema
    out = {}
    for schema, (name, _, _) in schemas.PUBLISHED.items():
        doc = json.loads((DOCS / name).read_text(encoding="utf-8"))
        jsonschema.Draft202012Validator.check_schema(doc)
        out[schema] = jsonschema.Draft202012Validator(doc)
    return out


@pytest.mark.parametrize("kind", sorted(READERS))
def test_real_artifacts_pass_the_published_schemas(good, validators, kind):
    doc = json.loads(good[kind].read_text())
    errors = list(validators[doc["schema"]].iter_errors(doc))
    assert not errors, errors[0].message


@pytest.mark.parametrize("kind,change", [
    ("material", set_key("alpha", -0.2)), ("material", set_key("fit", "x")),
    ("material", set_key("status", 5)), ("measurement", set_key("brdf_std", [[-1.0]])),
    ("lobes", set_key("n_samples", 20)), ("lobes", set_key("diffuse", [])),
    ("index", set_key("maps.0.extra", 1)), ("basis", set_key("bases", [])),
    ("report", set_key("image", {"width": 0, "height": 1})),
], ids=["alpha", "fit", "status", "std", "n_samples", "diffuse", "index", "bases",
        "report"])
def test_broken_artifacts_fail_the_published_schemas(good, validators, tmp_path, kind,
                                                     change):
    doc = json.loads(broken(good[kind], tmp_path, change).read_text())
    assert list(validators[doc["schema"]].iter_errors(doc))


def test_the_envelope_is_artifacts():
    from gonio_cli.artifact import ENVELOPE_KEYS

    assert tuple(schemas.envelope_fields("gonio.x", (1,))) == ENVELOPE_KEYS


@pytest.mark.parametrize("doc,message", [
    ({"bases": [{"n_lobes": 1, "exponents": [[8.0]]}]}, "has 2 dimensions, expected 1"),
    ({"bases": [{"n_lobes": 2, "exponents": [8.0, [8.0]]}]}, "not a numeric array"),
    ({"bases": [{"n_lobes": 1, "exponents": [float("nan")]}]}, "holds NaN or inf"),
    ({"bases": [{"n_lobes": 1, "exponents": [8.0]}], "exponent_range": [1.0]},
     "'exponent_range' has 1 values, expected 2"),
])
def test_array_messages(doc, message):
    full = {"schema": "gonio.lobe_basis", "schema_version": 1, "sample_set": "seed001",
            "channels": "xyz", "solver": "nnls", **doc}
    with pytest.raises(ArtifactError, match=re.escape(message)):
        schemas.LobeBasis.from_document(full, path="basis.json")


def test_prefilter_index_written_and_read_by_one_definition(tmp_path):
    """gonio prefilter writes index.json through the reader's definition: what it writes
    reads back, and a document the reader would refuse is not written at all."""
    index = schemas.PrefilterIndex(
        maps=[{"exponent": 1.0, "path": "prefiltered_E1.exr", "width": 8, "height": 4},
              {"exponent": 64.0, "path": "prefiltered_E64.exr", "width": 16, "height": 8,
               "method": "ring", "error_estimate": 0.002}],
        source={"width": 16, "height": 8, "channels": 3}, diffuse="prefiltered_E1.exr")
    path = tmp_path / "index.json"
    doc = schemas.write_prefilter_index(path, index, parameters={"exponents": [1, 64]})
    assert doc["schema"] == "gonio.prefilter" and doc["schema_version"] == 2
    assert schemas.read_prefilter_index(path) == index
    bad = tmp_path / "bad.json"
    broken = schemas.PrefilterIndex(maps=[{"exponent": 0.5, "path": "x.exr", "width": 8,
                                           "height": 4}])       # below the exponent range
    with pytest.raises(ArtifactError, match="exponent"):
        schemas.write_prefilter_index(bad, broken)
    assert not bad.exists()
