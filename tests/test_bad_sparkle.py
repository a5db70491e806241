"""gonio sparkle on options outside their ranges: one line naming the option, exit 2, no
texture (a huge or negative threshold would give an empty or full texture with exit 0)."""

from __future__ import annotations

import pytest
from bad_inputs import SAMPLE, assert_refused, run

PHOTOS = sorted((SAMPLE / "sparkle").glob("photo_ti*.png"))[:2]


@pytest.mark.parametrize("rule,parameter", [("mad", "1e300"), ("mad", "-1e300"),
                                            ("mad", "-1"), ("mad", "nan"),
                                            ("percentile", "0"), ("percentile", "1e3"),
                                            ("percentile", "-5")])
def test_rule_parameter_outside_its_range_is_refused(tmp_path, rule, parameter):
    out = tmp_path / "sparkle.png"
    code, err = run("sparkle", *PHOTOS, "-o", out, "--theta-i", "10,20", "--rule", rule,
                    "--parameter", parameter)
    assert_refused(code, err, names=("--parameter", rule), outputs=[out])


@pytest.mark.parametrize("angles", ["1e300,20", "10,inf", "-10,20"])
def test_angle_outside_its_range_is_refused(tmp_path, angles):
    out = tmp_path / "sparkle.png"
    code, err = run("sparkle", *PHOTOS, "-o", out, "--theta-i", angles)
    assert_refused(code, err, names=("(0, 90)",), outputs=[out])
