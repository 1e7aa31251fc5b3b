"""Claims and their verdicts.

A claim row is the SPH validation suite's :class:`terradyn.sph.suite.Check` (quantity, ours,
reference, source, tolerance, verdict); a :class:`Card` groups the rows of one published
statement with our figures. Every verdict comes from :func:`judge`, which reads the tolerance
text and compares the numbers of this run: none is written by hand.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ..sph.suite import Check

#: The report's words for a row's verdict (Check.describe() says pass / fail / no published number).
WORDS = {True: "matches", False: "differs", None: "no published number"}
_NUM = r"([-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?)"


def judge(ours, reference, tolerance: str | None) -> bool | None:
    """Whether ``ours`` meets ``tolerance``; None where there is nothing to compare with.

    Tolerances (text, as shown to the reader): ``"within X %"`` (|ours / reference - 1| <= X
    / 100), ``"within +-X"`` (|ours - reference| <= X, in the row's unit), ``"exact"``
    (ours == reference), ``"<= reference"`` / ``"<= RFT's"`` (ours <= reference), and bounds
    on ours alone: ``"> X"``, ``">= X"``, ``"< X"``, ``"<= X"``. None or an empty tolerance,
    or a missing or non-finite number, gives None (no published number to compare with)."""
    if not tolerance or ours is None or not math.isfinite(float(ours)):
        return None
    t = tolerance.strip().lower()
    ours = float(ours)
    ref = None if reference is None else float(reference)
    if ref is not None and not math.isfinite(ref):
        ref = None
    m = re.fullmatch(r"within\s+" + _NUM + r"\s*%", t)
    if m:
        return None if not ref else abs(ours / ref - 1) <= float(m.group(1)) / 100
    m = re.fullmatch(r"within\s+\+-\s*" + _NUM + r".*", t)
    if m:
        return None if ref is None else abs(ours - ref) <= float(m.group(1))
    if t == "exact":
        return None if ref is None else ours == ref
    m = re.fullmatch(r"(<=|>=|<|>)\s*(reference|rft's|" + _NUM + r")", t)
    if m:
        op, rhs = m.group(1), m.group(2)
        if rhs in ("reference", "rft's"):
            if ref is None:
                return None
            bound = ref
        else:
            bound = float(rhs)
        return {"<=": ours <= bound, ">=": ours >= bound, "<": ours < bound, ">": ours > bound}[op]
    raise ValueError(f"unknown tolerance {tolerance!r}")


def check(scene: str, quantity: str, ours, reference, source: str, tolerance: str | None = None,
          unit: str = "") -> Check:
    """A claim row whose verdict is :func:`judge` of its own numbers."""
    ours = None if ours is None else float(ours)
    reference = None if reference is None else float(reference)
    return Check(scene, quantity, ours, reference, source, tolerance or "none (no published number)",
                 judge(ours, reference, tolerance), unit)


def row(c: Check) -> dict:
    """A claim row for report.json: Check.describe() with the report's verdict word."""
    d = c.describe()
    d["passed"] = c.passed
    d["verdict"] = WORDS[c.passed]
    return d


@dataclass
class Card:
    """One published statement: our figures, the statement and its source, the claim rows."""
    id: str
    title: str
    statement: str
    source: str
    checks: list = field(default_factory=list)
    figures: list = field(default_factory=list)  # file names in the part's folder
    note: str = ""
    table: list = field(default_factory=list)  # extra rows of numbers (dicts) shown under the card

    @property
    def verdict(self) -> str:
        return card_verdict([c.passed for c in self.checks])

    def describe(self) -> dict:
        return {"id": self.id, "title": self.title, "statement": self.statement, "source": self.source,
                "note": self.note, "figures": list(self.figures), "table": self.table,
                "verdict": self.verdict, "claims": [row(c) for c in self.checks]}


def card_verdict(passed: list) -> str:
    """A card matches when every compared row does, differs when any differs, and has no
    published number when no row could be compared."""
    judged = [p for p in passed if p is not None]
    if not judged:
        return WORDS[None]
    return WORDS[all(judged)]
