"""What one fit produced (:class:`FitOutcome`): the record that the fits of :mod:`rcci.calib.fits`
return, :mod:`rcci.calib.fitting` runs and :mod:`rcci.calib.registry` / :mod:`rcci.calib.report` pass on."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class FitOutcome:
    """What a fit produced: the printed table, TOML sections, the raw results, and notes
    (warnings and assumptions) that are printed with the table and kept in the report."""

    kind: str
    table: str
    sections: dict[str, dict[str, Any]]
    results: Any
    extra: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    assumed: list[str] = field(default_factory=list)
    truth: str = ""        # what its logs were recorded against (rcci.calib.truth.truth_label), for [calib]
