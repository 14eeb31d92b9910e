"""Sim-to-real gap diagnosis (issue 7, DESIGN.md): where the gap lies, which unmodelled effect
causes it, and how far it shrinks once that effect is added, on maneuvers held out of the fit.

>>> from aerodelta.diagnose import default_vocabulary
>>> [c.name for c in default_vocabulary().for_coefficient("CY")][:3]
['lateral_asymmetry', 'sideforce_beta', 'rudder_effectiveness']
"""

from aerodelta.diagnose.core import SCHEMA, DiagnoseConfig, Diagnosis, diagnose
from aerodelta.diagnose.report import summary_text, write_outputs
from aerodelta.diagnose.select import SelectionConfig
from aerodelta.diagnose.vocabulary import Candidate, Vocabulary, default_vocabulary

__all__ = [
    "SCHEMA",
    "Candidate",
    "DiagnoseConfig",
    "Diagnosis",
    "SelectionConfig",
    "Vocabulary",
    "default_vocabulary",
    "diagnose",
    "summary_text",
    "write_outputs",
]
