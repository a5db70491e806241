"""Image files: compression levels (checked in the files' own bytes), the paletted and
1-bit PNG writers, reading stored integers, and SOURCE_DATE_EPOCH in EXR headers."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from gonio_cli import imageio
from gonio_cli.errors import InputError
from gonio_cli.imageio import (COMPRESSION, header_date_time, read_image, write_exr,
                               write_png, write_png_1bit, write_png_indexed)

#: zlib's FLEVEL header bits (RFC 1950 §2.2) for a deflate level: 0 for levels 0–1,
#: 1 for 2–5, 2 for 6 (the default), 3 for 7–9.
FLEVEL = {0: 0, 1: 0, 6: 2, 9: 3}

PALETTE = [[0, 0, 0], [255, 0, 0], [0, 255, 0], [0, 0, 255]]


def png_chunks(path) -> list[tuple[bytes, bytes]]:
    """(type, data) of every chunk of a PNG file (PNG spec §5.3), CRCs checked."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    chunks, pos = [], 8
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc
        chunks.append((kind, body))
        pos += 12 + length
    return chunks


def ihdr(path) -> dict:
    body = dict(png_chunks(path))[b"IHDR"]
    w, h, depth, colour = struct.unpack(">IIBB", body[:10])
    return {"width": w, "height": h, "bit_depth": depth, "colour_type": colour}


def deflate_flevel(path) -> int:
    idat = b"".join(body for kind, body in png_chunks(path) if kind == b"IDAT")
    return idat[1] >> 6


def labels(h=37, w=53, seed=0) -> np.ndarray:
    """Random labels 0–3 with runs (so that compression levels differ in size)."""
    rng = np.random.default_rng(seed)
    return np.repeat(rng.integers(0, 4, (h, (w + 2) // 3)), 3, axis=1)[:, :w].astype(np.uint8)


@pytest.mark.parametrize("level", list(COMPRESSION))
def test_every_png_writer_uses_the_named_deflate_level(tmp_path, level):
    zlib_level = COMPRESSION[level].png_zlib_level
    lab = labels()
    rgb = np.asarray(PALETTE, np.uint8)[lab]
    write_png(tmp_path / "rgb.png", rgb, compression=level)
    write_png_1bit(tmp_path / "bit.png", lab == 1, compression=level)
    write_png_indexed(tmp_path / "pal.png", lab, PALETTE, compression=level)
    for name in ("rgb.png", "bit.png", "pal.png"):
        assert deflate_flevel(tmp_path / name) == FLEVEL[zlib_level], name
    # lossless whatever the level
    np.testing.assert_array_equal(read_image(tmp_path / "rgb.png", keep_integers=True).pixels,
                                  rgb)
    np.testing.assert_array_equal(read_image(tmp_path / "pal.png", keep_integers=True).pixels,
                                  rgb)


def test_none_stores_and_fast_deflates(tmp_path):
    """(The order of the deflating levels' sizes depends on the data; their levels are
    checked in the zlib header above.)"""
    # runs of 12 equal labels: 3 equal bytes once packed 4 to a byte, which 'fast' (level
    # 1, run-length matching) must find
    rng = np.random.default_rng(0)
    lab = np.repeat(rng.integers(0, 4, (200, 25)), 12, axis=1)[:, :300].astype(np.uint8)
    sizes = {}
    for level in ("none", "fast"):
        write_png_indexed(tmp_path / f"{level}.png", lab, PALETTE, compression=level)
        sizes[level] = (tmp_path / f"{level}.png").stat().st_size
    # 'none' stores the 2-bit rows: 300 / 4 = 75 bytes + 1 filter byte, 200 rows
    assert sizes["none"] > 200 * 76
    # each run of 3 equal bytes costs a literal and a short match: at least a third goes
    assert sizes["fast"] < 2 / 3 * sizes["none"]


def test_balanced_is_the_libraries_default(tmp_path):
    """The writers' default reproduces files written before the levels existed."""
    import OpenImageIO as oiio

    rgb = np.asarray(PALETTE, np.uint8)[labels()]
    write_png(tmp_path / "ours.png", rgb)
    spec = oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "uint8")
    spec.attribute(imageio.META_PREFIX + "gonio_version", imageio.__version__)
    out = oiio.ImageOutput.create(str(tmp_path / "plain.png"))
    assert out.open(str(tmp_path / "plain.png"), spec)
    out.write_image(rgb)
    out.close()
    assert imageio.DEFAULT_COMPRESSION == "balanced"
    assert (tmp_path / "ours.png").read_bytes() == (tmp_path / "plain.png").read_bytes()


def test_indexed_png_is_two_bit_and_decodes_to_rgb(tmp_path):
    from PIL import Image as PILImage

    lab = labels()
    path = tmp_path / "mask.png"
    write_png_indexed(path, lab, PALETTE, {"method": "test"})
    assert ihdr(path) == {"width": 53, "height": 37, "bit_depth": 2, "colour_type": 3}
    img = read_image(path)
    assert img.pixels.shape == (37, 53, 3) and img.metadata["method"] == "test"
    expected = np.asarray(PALETTE, np.uint8)[lab]
    np.testing.assert_array_equal(np.round(img.pixels * 255).astype(np.uint8), expected)
    np.testing.assert_array_equal(np.asarray(PILImage.open(path).convert("RGB")), expected)
    with pytest.raises(ValueError, match="outside the 4-colour palette"):
        write_png_indexed(tmp_path / "bad.png", lab + 1, PALETTE)


def test_one_bit_png(tmp_path):
    mask = labels() == 2
    write_png_1bit(tmp_path / "m.png", mask, compression="fast")
    assert ihdr(tmp_path / "m.png")["bit_depth"] == 1
    np.testing.assert_array_equal(read_image(tmp_path / "m.png").pixels[:, :, 0] == 1.0, mask)


def test_keep_integers_returns_stored_values(tmp_path):
    import OpenImageIO as oiio

    ramp8 = np.arange(256, dtype=np.uint8).reshape(1, 256, 1).repeat(3, axis=2)
    write_png(tmp_path / "r8.png", ramp8)
    img = read_image(tmp_path / "r8.png", keep_integers=True)
    assert img.pixels.dtype == np.uint8 and not img.is_float
    np.testing.assert_array_equal(img.pixels, ramp8)
    # the float reading is the stored value times float32(1/255): what the halftone's
    # decoding table assumes (coverage.decode_table)
    as_float = read_image(tmp_path / "r8.png").pixels
    np.testing.assert_array_equal(as_float, ramp8.astype(np.float32) * np.float32(1 / 255))
    ramp16 = np.arange(0, 65536, 257, dtype=np.uint16).reshape(1, 256, 1).repeat(3, axis=2)
    spec = oiio.ImageSpec(256, 1, 3, "uint16")
    out = oiio.ImageOutput.create(str(tmp_path / "r16.png"))
    assert out.open(str(tmp_path / "r16.png"), spec)
    out.write_image(ramp16)
    out.close()
    img = read_image(tmp_path / "r16.png", keep_integers=True)
    assert img.pixels.dtype == np.uint16
    np.testing.assert_array_equal(img.pixels, ramp16)
    write_exr(tmp_path / "f.exr", np.full((2, 2, 3), 0.25, np.float32))
    img = read_image(tmp_path / "f.exr", keep_integers=True)
    assert img.pixels.dtype == np.float32 and img.is_float


@pytest.mark.parametrize("level", list(COMPRESSION))
def test_exr_compression_is_lossless_and_named_in_the_header(tmp_path, level):
    import OpenImageIO as oiio

    rng = np.random.default_rng(1)
    a = (rng.random((16, 24, 3)) * 1e4).astype(np.float32)
    write_exr(tmp_path / "a.exr", a, compression=level)
    np.testing.assert_array_equal(read_image(tmp_path / "a.exr").pixels, a)
    inp = oiio.ImageInput.open(str(tmp_path / "a.exr"))
    codec = inp.spec().get_string_attribute("compression")
    inp.close()
    assert codec == COMPRESSION[level].exr_codec.split(":")[0]


def test_source_date_epoch_makes_exr_reproducible(tmp_path, monkeypatch):
    import OpenImageIO as oiio

    a = np.linspace(0, 5, 48, dtype=np.float32).reshape(4, 4, 3)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1795448543")
    write_exr(tmp_path / "a.exr", a, {"source": "test"})
    write_exr(tmp_path / "b.exr", a, {"source": "test"})
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    inp = oiio.ImageInput.open(str(tmp_path / "a.exr"))
    stamp = inp.spec().get_string_attribute("DateTime")
    inp.close()
    # 1795448543 s after 1970-01-01T00:00:00Z is 2026-11-23T15:42:23Z
    assert stamp == "2026:11:23 15:42:23"
    # the argument wins over the environment
    write_exr(tmp_path / "c.exr", a, source_date_epoch=0)
    inp = oiio.ImageInput.open(str(tmp_path / "c.exr"))
    assert inp.spec().get_string_attribute("DateTime") == "1970:01:01 00:00:00"
    inp.close()


def test_header_date_time():
    assert header_date_time(0) == "1970:01:01 00:00:00"
    assert header_date_time("86399") == "1970:01:01 23:59:59"


@pytest.mark.parametrize("value", ["yesterday", "-5", "1.5", "99999999999999999999"])
def test_bad_source_date_epoch_is_one_line(monkeypatch, tmp_path, value):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", value)
    with pytest.raises(InputError, match="SOURCE_DATE_EPOCH") as info:
        write_exr(tmp_path / "a.exr", np.zeros((2, 2, 3), np.float32))
    assert "\n" not in str(info.value)
    assert not (tmp_path / "a.exr").exists()


def test_unset_or_empty_source_date_epoch_means_now(monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    assert header_date_time() is None
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "")
    assert header_date_time() is None


def test_unknown_compression_names_the_levels(tmp_path):
    with pytest.raises(InputError, match="none, fast, balanced, small"):
        write_png(tmp_path / "a.png", np.zeros((2, 2, 3), np.uint8), compression="max")
    assert not (tmp_path / "a.png").exists()
