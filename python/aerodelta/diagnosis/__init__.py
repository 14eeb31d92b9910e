"""Sim-to-real gap diagnosis (issue 7, DESIGN.md): where the gap lies, which unmodelled effect
causes it, and how far it shrinks once that effect is added, on maneuvers held out of the fit.

>>> from aerodelta.diagnosis import default_vocabulary
>>> [c.name for c in default_vocabulary().for_coefficient("CY")][:3]
['lateral_asymmetry', 'sideforce_beta', 'rudder_effectiveness']
"""

from aerodelta.diagnosis.core import SCHEMA, DiagnoseConfig, Diagnosis, diagnose
from aerodelta.diagnosis.report import summary_text, write_outputs
from aerodelta.diagnosis.select import SelectionConfig
from aerodelta.diagnosis.vocabulary import Candidate, Vocabulary, default_vocabulary

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
