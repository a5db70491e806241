"""``gonio report``'s colour sheets: each material's colour over θi and θo, the goniochromatic
shift at a glance."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..geometry import in_plane_cosines
from ..spectra import illuminant, spectrum_to_xyz, srgb_encode, xyz_to_linear_srgb
from .section import Inputs, Section

#: Angles of incidence of the sheets' lobe plots (deg).
SHEET_THETA_I_DEG = (15.0, 30.0, 45.0, 60.0, 75.0)
#: Outgoing angles (deg) of the lobe plots and swatches (in-plane, docs/conventions.md sign).
SHEET_THETA_O_DEG = np.arange(-88.0, 88.5, 1.0)
#: A direction whose linear sRGB has no channel above this shows no colour: drawn black.
MIN_CHANNEL = 1e-12


def direction_colours(material, theta_i_deg, theta_o_deg) -> tuple[np.ndarray, np.ndarray]:
    """The colour each in-plane direction shows under D65 and the BRDF's luminance.

    Radiance f(ωi, ωo) · cos θi · D65(λ) (E = 1) → XYZ (docs/conventions.md) → linear sRGB,
    normalised per direction so the largest channel is 1 (hue and saturation only; the
    lobe plot's radius carries the magnitude), then sRGB-encoded.
    Returns (rgb (n_i, n_o, 3) in [0, 1], Y of f under D65 (n_i, n_o), sr⁻¹).
    """
    ti, to = np.meshgrid(np.asarray(theta_i_deg, float), np.asarray(theta_o_deg, float),
                         indexing="ij")
    f = material.evaluate(in_plane_cosines(ti.ravel(), to.ravel()))
    f = f.reshape(ti.shape + (f.shape[-1],))
    wl = material.wavelength_nm
    d65 = illuminant("D65", wl)
    xyz_f = spectrum_to_xyz(f * d65, wl)
    rgb = np.maximum(xyz_to_linear_srgb(xyz_f * np.cos(np.radians(ti))[..., None]), 0.0)
    peak = rgb.max(axis=-1, keepdims=True)
    rgb = np.where(peak > MIN_CHANNEL, rgb / np.maximum(peak, MIN_CHANNEL), 0.0)
    return srgb_encode(rgb), xyz_f[..., 1]


def sheet_plot(path: Path, title: str, material) -> None:
    """A material sheet: in-plane lobe plots per θi (polar, θo from the normal, radius
    Y of f normalised per θi, points coloured by the colour each direction shows) over a
    swatch strip (rows θi, columns θo)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rgb, y = direction_colours(material, SHEET_THETA_I_DEG, SHEET_THETA_O_DEG)
    n = len(SHEET_THETA_I_DEG)
    fig = plt.figure(figsize=(2.3 * n, 4.6), dpi=100)
    th = np.radians(SHEET_THETA_O_DEG)
    for k, ti in enumerate(SHEET_THETA_I_DEG):
        ax = fig.add_subplot(2, n, k + 1, projection="polar")
        r = y[k] / max(float(y[k].max()), MIN_CHANNEL)
        ax.plot(th, r, color="0.6", lw=0.6)
        ax.scatter(th, r, c=rgb[k], s=9)
        ax.plot([-np.radians(ti)] * 2, [0, 1.05], color="orange", lw=1)  # the light
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_thetamin(-90)
        ax.set_thetamax(90)
        ax.set_yticklabels([])
        ax.set_title(f"θi = {ti:g}°", fontsize=9)
        ax.tick_params(labelsize=6)
    ax = fig.add_subplot(2, 1, 2)
    ax.imshow(rgb, aspect="auto", interpolation="nearest",
              extent=(SHEET_THETA_O_DEG[0], SHEET_THETA_O_DEG[-1], n - 0.5, -0.5))
    ax.set_yticks(range(n), [f"θi {t:g}°" for t in SHEET_THETA_I_DEG], fontsize=7)
    ax.set_xlabel("viewing angle θo (deg; > 0 the specular side, θo = θi the mirror)")
    ax.set_title("colour swatch over viewing angle (D65, hue normalised)", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def sheets_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
    plots, items = {}, []
    for k, (label, mat) in enumerate(inputs.sheets):
        slug = "".join(ch if ch.isalnum() else "-" for ch in label.lower()).strip("-")
        name = f"sheet-{k:02d}-{'-'.join(p for p in slug.split('-') if p)}.png"
        rgb, _ = direction_colours(mat, SHEET_THETA_I_DEG, SHEET_THETA_O_DEG)
        mirror = [rgb[i, int(np.argmin(np.abs(SHEET_THETA_O_DEG - t)))].tolist()
                  for i, t in enumerate(SHEET_THETA_I_DEG)]
        items.append({"material": label, "model": mat.model, "file": name,
                      "mirror_srgb": mirror})
        plots[name] = (lambda path, label=label, mat=mat: sheet_plot(path, label, mat))
    md = ("Per material: the in-plane BRDF over θo for each θi (polar; radius the luminance "
          "of f under D65, normalised per θi; the orange line is the light), each point "
          "coloured by the colour that direction shows (XYZ of f·cos θi under D65 → sRGB, "
          "normalised so its largest channel is 1), and a swatch strip of that colour over "
          "viewing angle.\n\n" + "\n\n".join(f"**{i['material']}** ({i['model']})\n\n"
                                             f"![{i['material']}]({i['file']})" for i in items))
    return Section("sheets", "Material sheets", {"sheets": items,
                   "theta_i_deg": list(SHEET_THETA_I_DEG)}, md, plots)
