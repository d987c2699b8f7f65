"""Peg-in-hole insertion with the Panda in MJX."""

from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.peg_insert.env import PegInsert, PegInsertInfo, PegInsertSim
from jaxarm.envs.peg_insert.params import PegInsertParams

__all__ = ["CONTROL_DT", "PegInsert", "PegInsertInfo", "PegInsertParams", "PegInsertSim"]
