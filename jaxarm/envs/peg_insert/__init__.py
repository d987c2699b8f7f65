"""Peg-in-hole insertion with the Panda in MJX."""

from jaxarm.envs.peg_insert.env import CONTROL_DT, PegInsert, PegInsertInfo, PegInsertSim
from jaxarm.envs.peg_insert.params import PegInsertParams

__all__ = ["CONTROL_DT", "PegInsert", "PegInsertInfo", "PegInsertParams", "PegInsertSim"]
