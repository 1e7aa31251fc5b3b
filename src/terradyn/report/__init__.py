"""The thesis reproduced as one report (``terradyn reproduce``): every result of chapters 2-4
that terradyn can produce, each published number beside ours with a computed verdict, as
``index.html`` (self-contained) and ``report.json``. See :mod:`terradyn.report.run`."""
from .run import PART_NAMES, TIERS, reproduce, tier_settings
from .verdict import Card, card_verdict, check, judge

__all__ = ["reproduce", "TIERS", "PART_NAMES", "tier_settings", "judge", "check", "Card", "card_verdict"]
