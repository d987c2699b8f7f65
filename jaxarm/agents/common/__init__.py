"""Pieces every learner shares: configs, networks, the trainer protocol, evaluation, checkpoints."""
