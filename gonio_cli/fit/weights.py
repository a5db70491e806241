"""``gonio fit --weights``: per-configuration weights read from a CSV
``theta_i_deg,theta_o_deg,weight``, checked against the measurement they weight."""

from __future__ import annotations

import os

import numpy as np

from ..csvio import read_table
from ..errors import InputError
from ..schemas import MAX_MAGNITUDE, Measurement

#: The one header a weights file has.
HEADER = ["theta_i_deg", "theta_o_deg", "weight"]


def read_weights(path: str | os.PathLike, m: Measurement) -> np.ndarray:
    """Per-configuration weights (N,) from a CSV theta_i_deg,theta_o_deg,weight; 1 for the
    configurations it does not list. Every row must name a measured configuration. Split
    by ingest's one CSV reader (delimiters, BOM, comments, line numbers).

    Raises
    ------
    InputError
        A wrong header, a row that is not three numbers, a weight outside
        [0, MAX_MAGNITUDE] or a configuration the measurement does not have (file, row and
        column named).
    """
    table = read_table(path)
    if table.header != HEADER:
        raise InputError(f"header is {','.join(table.header) or 'missing'}", path=path,
                         row=table.header_line,
                         fix="the header must be theta_i_deg,theta_o_deg,weight")
    w = np.ones(m.theta_i_deg.shape)
    for row, line in zip(table.cells, table.lines):
        try:
            ti, to, wt = (float(c) for c in row)
        except ValueError:
            raise InputError(f"expected three numbers, got {','.join(row)}", path=path,
                             row=int(line), fix="theta_i_deg,theta_o_deg,weight per line"
                             ) from None
        if not (0 <= wt <= MAX_MAGNITUDE):                    # also NaN
            raise InputError(f"weight {wt:g} is not a finite number in [0, "
                             f"{MAX_MAGNITUDE:g}]", path=path,
                             row=int(line), column="weight")
        hit = (np.abs(m.theta_i_deg - ti) < 1e-6) & (np.abs(m.theta_o_deg - to) < 1e-6)
        if not hit.any():
            raise InputError(f"no measured configuration has theta_i_deg={ti:g}, "
                             f"theta_o_deg={to:g}", path=path, row=int(line),
                             fix="list only configurations of the measurement")
        w[hit] = wt
    return w
