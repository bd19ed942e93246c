"""Identification: the problem a fit solves, the polish, identifiability, `identify`
and the periodic steady-state fit, as one pipeline (see `_identify.py`)."""
