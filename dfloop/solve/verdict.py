"""Every prediction classified: confirmed by an exact orbit, an artefact of the describing function, or not checked.

A :class:`~dfloop.solve.result.LimitCycle` from ``predict_limit_cycles(..., exact=True)`` carries the outcome of
:func:`dfloop.exact_cycle` (``cycle.exact``); :func:`classify` reads it:

- **confirmed**: an exact periodic orbit exists near the prediction; ``distance`` is the larger of |ln(A/A_exact)|
  and |ln(w/w_exact)| (0.01 ~ 1 %), ``detail`` gives the orbit and its Floquet stability;
- **artefact**: no periodic orbit near the prediction, with the evidence exact_cycle gathered (where the motions
  started on and around it went: another cycle, rest, divergence, or a motion not periodic within the runs; or,
  where they split between two fates, the motion on the boundary between them, followed by edge tracking
  (:mod:`dfloop.hybrid.edge`), comes to rest instead of becoming periodic);
- a tabulated N (dynamic backlash) is certified at the point of use (:func:`dfloop.exact.table_certificate`:
  the table's error estimate and validity at the cycle, N re-simulated there): the detail says so, and an
  artefact is only concluded from a table value that is valid and not replaced by its re-simulation;
- **not checked**: no exact orbit was asked for (``exact=False``), the loop has no exact engine here (the
  reason), or the check was inconclusive (shooting failed from a motion that looked periodic, or the motions
  around the prediction split between rest and divergence, where an unstable orbit may lie, and edge tracking
  on the boundary between them neither converged to one nor showed the boundary at rest).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Verdict", "classify", "exact_kind", "table_words", "CONFIRMED", "ARTEFACT", "NOT_CHECKED"]

CONFIRMED, ARTEFACT, NOT_CHECKED = "confirmed", "artefact", "not checked"
_ARTEFACT_OUTCOMES = {"another cycle": "the motions go to another cycle", "rest": "the motions decay to rest",
                      "divergence": "the motions diverge",
                      "not periodic": "the motions are not periodic within the runs",
                      "edge rest": "the motion on the boundary between the starts' fates (edge tracking) comes to "
                                   "rest, no periodic orbit on it"}


@dataclass(frozen=True)
class Verdict:
    """What is known of one prediction: ``kind`` (``"confirmed"``, ``"artefact"``, ``"not checked"``), ``detail``
    (the orbit, the evidence, or the reason), ``distance`` (confirmed only: max |ln(A/A_exact)|, |ln(w/w_exact)|)."""

    kind: str
    detail: str
    distance: float | None = None

    def __str__(self) -> str:
        return f"{self.kind}: {self.detail}" if self.detail else self.kind


def exact_kind(ex) -> str:
    """The kind (``"confirmed"``, ``"artefact"``, ``"not checked"``) an :class:`~dfloop.exact.ExactCycle` alone
    establishes."""
    if ex.success:
        return CONFIRMED
    extra = getattr(ex, "extra", None) or {}
    cert = extra.get("table")
    if cert and (cert["status"] == "replaced" or not cert["valid"]):
        return NOT_CHECKED            # the prediction itself is uncertain (see classify)
    return ARTEFACT if extra.get("outcome") in _ARTEFACT_OUTCOMES else NOT_CHECKED


def table_words(cert: dict | None) -> str:
    """What the certificate of a tabulated N at the cycle says (``""`` without one; see
    :func:`dfloop.exact.table_certificate`)."""
    if not cert:
        return ""
    n = abs(cert["table"]) or 1.0
    head = f"N from a table: error estimate {cert['error'] / n:.1e} relative{'' if cert['valid'] else ', not valid'}"
    if cert["status"] == "confirmed":
        return f"{head}; re-simulated at the cycle: confirmed ({cert['difference'] / n:.1e} relative)"
    if cert["status"] == "replaced":
        words = (f"{head}; re-simulated at the cycle: replaced (the direct N differs by {cert['difference'] / n:.1e} "
                 f"relative, {cert['difference'] / cert['error']:.3g} error estimates)")
        if cert.get("refined") is not None:
            A, w = cert["refined"]
            words += f"; the root with the direct N: A={A:.6g}, w={w:.6g} rad/s"
        else:
            words += f"; no root with the direct N ({cert.get('refine_message', '')})"
        return words
    return f"{head}; not re-simulated (no direct evaluation of this element)"


def classify(cycle) -> Verdict:
    """The :class:`Verdict` of a predicted cycle (from its ``exact`` attachment; see the module notes).

    A tabulated N (``exact.extra["table"]``, :func:`dfloop.exact.table_certificate`) is accounted for: its
    certificate is stated in the detail, and an "artefact" needs a table value that its re-simulation confirmed
    (or at least a valid one): when the direct value replaced the table's, or the table is not valid at the
    cycle, the prediction itself may be misplaced and the answer is "not checked"."""
    ex = getattr(cycle, "exact", None)
    if ex is None:
        return Verdict(NOT_CHECKED, "no exact orbit asked for (predict_limit_cycles(..., exact=True) or exact_cycle)")
    extra = getattr(ex, "extra", None) or {}
    cert = extra.get("table")
    table = table_words(cert)
    suffix = f"; {table}" if table else ""
    if ex.success:
        d = max(abs(math.log(cycle.amplitude / ex.amplitude)), abs(math.log(cycle.frequency / ex.frequency)))
        return Verdict(CONFIRMED, f"exact orbit A={ex.amplitude:.6g}, w={ex.frequency:.6g} rad/s, "
                                  f"{'stable' if ex.stable else 'unstable'}, {100 * d:.3g} % away{suffix}", d)
    outcome = extra.get("outcome")
    if outcome in _ARTEFACT_OUTCOMES and cert and (cert["status"] == "replaced" or not cert["valid"]):
        return Verdict(NOT_CHECKED, f"inconclusive: the tabulated N at the prediction is not certain ({table}), so "
                                    f"the prediction may be misplaced; near it: {_ARTEFACT_OUTCOMES[outcome]} "
                                    f"({ex.message})")
    if outcome in _ARTEFACT_OUTCOMES:
        return Verdict(ARTEFACT, f"no periodic orbit near it: {_ARTEFACT_OUTCOMES[outcome]} ({ex.message}){suffix}")
    if outcome == "not checked":
        return Verdict(NOT_CHECKED, ex.message.removeprefix("not checked: "))
    return Verdict(NOT_CHECKED, f"inconclusive: {ex.message}")
