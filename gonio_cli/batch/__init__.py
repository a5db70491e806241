"""``gonio batch``: a plan of gonio jobs run on Dask, locally or on a cluster.

The package is a pure core behind the thin shell :mod:`gonio_cli.commands.batch`:

* :mod:`.plan` reads a plan (TOML) into :class:`~.plan.Job` records and checks the job
  graph (duplicate keys or outputs, missing inputs, cycles) before anything runs;
* :mod:`.jobs` runs one job inside a worker through gonio's own CLI (no subprocess), with
  the idempotence test (input sha256, parameters, gonio version) and the manifest record;
* :mod:`.journal` keeps ``OUTDIR/manifest.jsonl`` as a journal (a record appended and
  fsync'ed per finished job), the workers' receipts and the output folder's lock;
* :mod:`.engine` submits the graph to Dask distributed (futures depending on futures) and
  collects the records; it is the only module that imports Dask;
* :mod:`.sheet` writes the static contact sheet ``OUTDIR/index.html``.

The plan format and a cluster set-up are in docs/batch.md.
"""

from __future__ import annotations

#: Schema of the lines of ``OUTDIR/manifest.jsonl`` (one JSON record per job).
MANIFEST_SCHEMA = "gonio.batch-manifest"
#: v2: a journal, a line appended per finished job (a key may repeat: the last counts).
MANIFEST_SCHEMA_VERSION = 2
#: The manifest and the contact sheet, inside the output folder.
MANIFEST_NAME = "manifest.jsonl"
SHEET_NAME = "index.html"
