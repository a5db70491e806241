"""CxF3 in and out: ``gonio export --to cxf --at M`` and ``gonio ingest FILE.cxf``.

1. Round trip: the spectra written (the material's R = π f at the measurement's
   configurations, computed here from the material itself) read back with ``gonio
   ingest`` to the same f within 1e-6, at the same angles.
2. A CxF3 file in the form multi-angle instruments write (``cc:`` prefix, a
   ColorSpecification per geometry with MultiAngle/BRDFAngle, 400-700 nm) reads in with
   its angles by the conventions' rule θo = θi − a.
3. Bad input is one line.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.geometry import in_plane_cosines
from gonio_cli.samples import sample_data_dir
from gonio_cli.schemas import read_material, read_measurement

pytest.importorskip("colour_cxf", reason="colour-cxf is not installed (gonio's exchange "
                    "extra: pip install '.[exchange]'; make test installs it)")


@pytest.fixture(scope="module")
def paint(tmp_path_factory):
    """(material, multi-angle measurement, exported .cxf) of the sample car paint."""
    from gonio_cli import cli

    tmp = tmp_path_factory.mktemp("cxf")
    meas, mat, out = (tmp / "ma.measurement.json", tmp / "paint.material.json",
                      tmp / "paint.cxf")
    for args in (["ingest", sample_data_dir() / "carpaint_multiangle.csv", "--quantity",
                  "reflectance-factor", "-o", meas],
                 ["fit", meas, "-o", mat, "--model", "cook-torrance"],
                 ["export", mat, "--to", "cxf", "--at", meas, "-o", out]):
        assert cli.run([str(a) for a in args]) == 0
    return mat, meas, out


def test_round_trip_reads_back_the_same_spectra(paint, run_gonio, tmp_path):
    mat, meas, out = paint
    back = tmp_path / "back.measurement.json"
    r = run_gonio("ingest", out, "-o", back)
    assert r.exit_code == 0, r.stderr
    m, b, material = read_measurement(meas), read_measurement(back), read_material(mat)
    # the geometries come back in the file's order: match them by angle
    key = lambda x: np.lexsort((x.theta_o_deg, x.theta_i_deg))  # noqa: E731
    i, j = key(m), key(b)
    np.testing.assert_array_equal(b.theta_i_deg[j], m.theta_i_deg[i])
    np.testing.assert_allclose(b.theta_o_deg[j], m.theta_o_deg[i], atol=1e-9)
    truth = material.evaluate(in_plane_cosines(m.theta_i_deg, m.theta_o_deg))[i]
    np.testing.assert_allclose(b.brdf[j], truth, rtol=1e-6, atol=1e-12)
    assert b.quantity == "reflectance-factor"


def test_the_file_names_its_geometries_as_cxf3_does(paint):
    from colour_cxf import cxf3, read_cxf_from_file

    doc = read_cxf_from_file(paint[2])
    specs = {s.id: s for s in doc.resources.color_specification_collection.color_specification}
    angle = specs["CS_45as15"].measurement_spec.geometry_choice.choice.brdfangle[0]
    assert (angle.illumination_angle, angle.aspecular) == (45.0, 15.0)
    (obj,) = doc.resources.object_collection.object_value
    spectra = [v for v in obj.color_values.choice if isinstance(v, cxf3.ReflectanceSpectrum)]
    assert len(spectra) == len(specs) == 9 and spectra[0].start_wl == 380


INSTRUMENT = """<?xml version="1.0" encoding="UTF-8"?>
<cc:CxF xmlns:cc="http://colorexchangeformat.com/CxF3-core">
  <cc:FileInformation><cc:Creator>X-Rite MA-T12</cc:Creator>
    <cc:CreationDate>2024-05-02T10:00:00+02:00</cc:CreationDate></cc:FileInformation>
  <cc:Resources>
    <cc:ObjectCollection>
      <cc:Object ObjectType="Sample" Name="blue metallic" Id="1">
        <cc:CreationDate>2024-05-02T10:00:00+02:00</cc:CreationDate>
        <cc:ColorValues>{spectra}</cc:ColorValues>
      </cc:Object>
    </cc:ObjectCollection>
    <cc:ColorSpecificationCollection>{specs}</cc:ColorSpecificationCollection>
  </cc:Resources>
</cc:CxF>"""
SPEC = """
      <cc:ColorSpecification Id="{id}">
        <cc:MeasurementSpec>
          <cc:MeasurementType>Spectrum_Reflectance</cc:MeasurementType>
          <cc:GeometryChoice><cc:MultiAngle><cc:BRDFAngle>
            <cc:IlluminationAngle>{ti}</cc:IlluminationAngle>
            <cc:Aspecular>{a}</cc:Aspecular>
          </cc:BRDFAngle></cc:MultiAngle></cc:GeometryChoice>
          <cc:WavelengthRange StartWL="400" Increment="10"/>
        </cc:MeasurementSpec>
      </cc:ColorSpecification>"""
#: An MA-T12's geometries (θi, aspecular): its 45° ring and one 15° and one 75° light.
GEOMETRIES = ((45, -15), (45, 15), (45, 25), (45, 45), (45, 75), (45, 110), (15, 15),
              (75, 25))


def test_an_instrument_file_reads_in_with_its_angles(run_gonio, tmp_path):
    wl = np.arange(400, 701, 10)
    values = {g: 0.05 + 0.5 * k / len(GEOMETRIES) + 0.1 * np.sin(wl / 50.0 + k)
              for k, g in enumerate(GEOMETRIES)}
    spectra = "".join(f'\n<cc:ReflectanceSpectrum Name="{ti}as{a}" StartWL="400" '
                      f'ColorSpecification="M{ti}_{a}">{" ".join(f"{v:.6f}" for v in values[(ti, a)])}'
                      '</cc:ReflectanceSpectrum>' for ti, a in GEOMETRIES)
    specs = "".join(SPEC.format(id=f"M{ti}_{a}", ti=ti, a=a) for ti, a in GEOMETRIES)
    path = tmp_path / "instrument.cxf"
    path.write_text(INSTRUMENT.format(spectra=spectra, specs=specs))
    out = tmp_path / "m.json"
    r = run_gonio("ingest", path, "--grid-nm", "400:700:10", "-o", out)
    assert r.exit_code == 0, r.stderr
    m = read_measurement(out)
    # θo = θi − a: 45as-15 → 60°, 45as45 → 0°, 45as110 → −65° (docs/conventions.md)
    got = {(float(ti), float(to)) for ti, to in zip(m.theta_i_deg, m.theta_o_deg)}
    assert got == {(float(ti), float(ti - a)) for ti, a in GEOMETRIES}
    k = int(np.flatnonzero((m.theta_i_deg == 45) & (m.theta_o_deg == -65))[0])
    np.testing.assert_allclose(m.brdf[k], np.round(values[(45, 110)], 6) / np.pi, rtol=1e-9)


@pytest.mark.parametrize("args, says", [
    (["--to", "cxf", "-o", "{tmp}/x.cxf"], "--at"),
    (["--to", "cxf", "--at", "{meas}", "-o", "{tmp}/x.xml"], "--output"),
])
def test_bad_export_options_are_one_line(paint, run_gonio, tmp_path, args, says):
    mat, meas, _ = paint
    r = run_gonio("export", mat, *[a.format(tmp=tmp_path, meas=meas) for a in args])
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_a_mirror_configuration_is_refused(tmp_path, run_gonio, paint):
    from gonio_cli import cli

    meas = tmp_path / "coat.measurement.json"
    assert cli.run(["ingest", str(sample_data_dir() / "coat_paint.csv"), "-o", str(meas)]) == 0
    r = run_gonio("export", paint[0], "--to", "cxf", "--at", meas, "-o", tmp_path / "c.cxf")
    assert r.exit_code == 2 and "beyond CxF3's limit" in r.stderr
    assert not (tmp_path / "c.cxf").exists()


def test_not_a_cxf_file_is_one_line(run_gonio, tmp_path):
    bad = tmp_path / "bad.cxf"
    bad.write_text("<html></html>")
    r = run_gonio("ingest", bad, "-o", tmp_path / "m.json")
    assert r.exit_code == 2 and "bad.cxf" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
