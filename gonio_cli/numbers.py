"""One grammar for every option that takes a list of numbers, one wording for its errors.

An option such as ``--exponents``, ``--theta-i-deg``, ``--view-angles-deg`` or
``--grid-nm`` takes numbers separated by commas, each item a number or an inclusive range
``START:STOP:STEP`` (``10:70:10`` is 10, 20, … 70): ``1,8,64``, ``-80:85:5,44,46``. An
option states what it accepts as a :class:`NumberList` (its name, an example, the unit, the
range of a value, whether it takes one range only, as ``--grid-nm`` does) and
:meth:`NumberList.parse` reads it. A bad list is one
:class:`~gonio_cli.errors.InputError` of one form for every option::

    --theta-i-deg '1,,x': item 2 is empty; numbers or START:STOP:STEP ranges separated by
    commas, in deg within [0, 90), e.g. --theta-i-deg 10:70:10

(the CLI names the option as the user typed it, :func:`gonio_cli.commands.as_typed_in`).
Standard library only: the typer shells parse their lists before any core is loaded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import InputError

#: Most values a list may expand to, unless the option says fewer: a range with a typo in
#: its step (``0:80:1e-9``) is refused before it is expanded, not after it filled memory.
MAX_VALUES = 100_000

#: How far from a whole number of steps STOP − START may be (in steps): float noise in
#: ``0:1:0.1``, not a range that misses its end.
STEP_TOLERANCE = 1e-6


def inclusive_count(start: float, stop: float, step: float) -> int | None:
    """How many values ``START:STOP:STEP`` holds, both ends included, or None when STEP is
    not positive, STOP < START, or STOP − START is not a whole number of steps (to
    :data:`STEP_TOLERANCE` of a step).

    >>> inclusive_count(10.0, 30.0, 10.0)
    3
    """
    n = (stop - start) / step if step > 0 else -1.0
    if n < 0 or abs(n - round(n)) > STEP_TOLERANCE:
        return None
    return int(round(n)) + 1


def inclusive_range(start: float, stop: float, step: float) -> list[float] | None:
    """The values of ``START:STOP:STEP``, both ends included (``start + k step``, as
    ``start + step * numpy.arange(n)``), or None as :func:`inclusive_count`.

    >>> inclusive_range(10.0, 30.0, 10.0)
    [10.0, 20.0, 30.0]
    """
    n = inclusive_count(start, stop, step)
    return None if n is None else [start + step * float(k) for k in range(n)]


@dataclass(frozen=True)
class NumberList:
    """What a number-list option accepts.

    Parameters
    ----------
    option : the option as its help spells it (``--theta-i-deg``); errors name it.
    example : a good value, shown in every error's fix (``10:70:10``).
    unit : the values' unit as messages write it (``deg``, ``nm``), or "".
    lo, hi, lo_open, hi_open : the range of every value (None: unbounded); a value outside
        it is an error naming the value. Checks a core makes anyway (an exponent in
        [1, 1e6]) stay in the core.
    one_range : the option takes exactly one ``START:STOP:STEP`` (``--grid-nm``).
    max_count, noun : at most this many values (``4001 samples``).
    """

    option: str
    example: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    one_range: bool = False
    max_count: int = MAX_VALUES
    noun: str = "values"

    def range_text(self) -> str:
        """``[0, 90)``, ``(0, 100000]``, or "" without bounds."""
        if self.lo is None and self.hi is None:
            return ""
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"

    def fix(self) -> str:
        """The one fix of every error of this option: the grammar, unit, range, example."""
        grammar = ("one START:STOP:STEP range" if self.one_range else
                   "numbers or START:STOP:STEP ranges separated by commas")
        within = self.range_text()
        where = " ".join(p for p in (f"in {self.unit}" if self.unit else "",
                                     f"within {within}" if within else "") if p)
        most = f"at most {self.max_count} {self.noun}" if self.max_count != MAX_VALUES else ""
        return ", ".join(p for p in (grammar, where, most) if p) + \
            f", e.g. {self.option} {self.example}"

    def error(self, spec, what: str, path=None) -> InputError:
        """``{option} {spec!r}: {what}`` with :meth:`fix`: for this option's other checks
        too (``--grid-nm`` needs two wavelengths), so that they read the same."""
        return InputError(f"{self.option} {str(spec)!r}: {what}", path=path, fix=self.fix())

    def outside(self, x: float) -> bool:
        """Is ``x`` outside the option's range (NaN is)?"""
        return not ((self.lo is None or (x > self.lo if self.lo_open else x >= self.lo))
                    and (self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)))

    def parse(self, spec, path=None) -> list[float]:
        """The values of ``spec`` in the order given (ranges expanded).

        ``path``: the input the values are for, named first in an error. A value may be
        ``inf`` (then outside any finite range), never NaN.

        Raises
        ------
        InputError
            One line, ``{option} {spec!r}: {what is wrong}; {fix}``.
        """
        text = str(spec)
        if not text.strip():
            raise self.error(spec, "is empty", path)
        values: list[float] = []
        items = [item.strip() for item in text.split(",")]
        for k, item in enumerate(items, start=1):
            values += self._item(spec, item, k, len(values), path)
        if self.one_range and (len(items) != 1 or ":" not in items[0]):
            raise self.error(spec, "is not one START:STOP:STEP range", path)
        bad = next((v for v in values if self.outside(v)), None)
        if bad is not None:
            unit = f" {self.unit}" if self.unit else ""
            raise self.error(spec, f"{bad:g}{unit} is outside {self.range_text()}", path)
        return values

    def _item(self, spec, item: str, k: int, before: int, path) -> list[float]:
        """The values of one item (the ``k``-th; ``before`` values came before it)."""
        if not item:
            raise self.error(spec, f"item {k} is empty", path)
        try:
            numbers = [float(p) for p in item.split(":")]
        except ValueError:
            numbers = []
        if len(numbers) == 1 and not math.isnan(numbers[0]):
            return numbers
        if len(numbers) != 3 or not all(math.isfinite(x) for x in numbers):
            raise self.error(spec, f"{item!r} is not a number or START:STOP:STEP", path)
        n = inclusive_count(*numbers)
        if n is None:
            raise self.error(spec, f"range {item!r} needs STEP > 0, START <= STOP and "
                                   "STOP - START a multiple of STEP", path)
        if before + n > self.max_count:
            raise self.error(spec, f"{item!r} holds {n:.3g} {self.noun}, more than "
                                   f"{self.max_count}", path)
        return inclusive_range(*numbers)
