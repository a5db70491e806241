"""``python -m gonio_cli.schemas DIR`` (``make schemas``): write the published JSON Schemas
into DIR (:func:`gonio_cli.schemas.publish.main`)."""

from .publish import main

raise SystemExit(main())
