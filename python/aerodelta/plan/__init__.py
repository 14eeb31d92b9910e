"""Campaign design before flying (issue 21): Monte Carlo studies of a flight test matrix on a
distributed engine (Dask). See ``docs/plan.md``.

:func:`run_plan` flies N seeded virtual campaigns of a test matrix, fits (and optionally
diagnoses) each on the cluster's workers and reports, per parameter and alpha range, the
predicted standard error, band width and probability of being identified, per effect the
probability the diagnosis names it, and a recommendation; :func:`compare_plans` puts two
matrices side by side; :func:`run_rolloff_study` runs the roll-off Monte Carlo in seeded
chunks on the same engine.
"""

from aerodelta.plan.matrix import Matrix, load_matrix
from aerodelta.plan.rolloff import RolloffStudy, run_rolloff_study
from aerodelta.plan.study import PlanResult, compare_plans, read_summary, run_plan

__all__ = [
    "Matrix",
    "PlanResult",
    "RolloffStudy",
    "compare_plans",
    "load_matrix",
    "read_summary",
    "run_plan",
    "run_rolloff_study",
]
