"""gonio: goniometer spectra to fitted goniochromatic BRDFs and rendered images.

Shared foundations (one place each):

- :mod:`gonio_cli.errors`    the one error type the CLI turns into a one-line message
- :mod:`gonio_cli.artifact`  self-describing JSON artifacts, atomic writes, provenance
- :mod:`gonio_cli.schemas`   every artifact's one definition and its published JSON Schema
- :mod:`gonio_cli.outputs`   each command's outputs as one transaction (:mod:`gonio_cli.folders`
  below it: making output folders)
- :mod:`gonio_cli.makers`    which command makes each artifact (the fix of a wrong input)
- :mod:`gonio_cli.numbers`   the one grammar of number-list options (``1,8,64``, ``0:80:10``)
- :mod:`gonio_cli.spectra`   the working spectral grid, resampling, colour helpers
- :mod:`gonio_cli.geometry`  in-plane goniometer geometry, half vector (seed 000 eq. 1, 6)
- :mod:`gonio_cli.brdf`      every reflectance model (seed 000 eqs. 2-7, seed 004 eqs. 9-12)
- :mod:`gonio_cli.brdf_jacobians` ∂ log of the microfacet terms, for the fits
- :mod:`gonio_cli.log`       warnings and progress bars, silent with ``--quiet``

Stages (pure numpy cores): :mod:`gonio_cli.ingest`, :mod:`gonio_cli.fit`.
Their typer shells live in :mod:`gonio_cli.commands`.
"""

__version__ = "0.1.0"
