"""Trained policies outside the learner: a numpy forward pass, and what writes a run's exported forms.

`jaxarm.export.numpy_policy` imports numpy alone (with jaxarm's package modules that import no JAX), so a
robot's computer needs neither JAX nor the learner state. `jaxarm.export.policy` (JAX) builds the exported forms
from a learner state. This package's own import must stay free of JAX.
"""
