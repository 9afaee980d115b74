"""Evaluation metrics (DESIGN §7): POR, Instantiation Distance, MMD / COV / 1-NNA, alignment,
diversity, validity; and the `artformer eval` / `artformer bench` commands.

    from model.metrics import part_overlap_ratio, instantiation_distance, set_metrics
"""
from .distribution import SetMetrics, coverage, mmd, one_nna, set_metrics
from .instantiation import (PosedClouds, chamfer_matrix, diversity, id_matrix,
                            instantiation_distance, posed_clouds)
from .por import PORResult, part_overlap_ratio

__all__ = ["PORResult", "PosedClouds", "SetMetrics", "chamfer_matrix", "coverage", "diversity",
           "id_matrix", "instantiation_distance", "mmd", "one_nna", "part_overlap_ratio",
           "posed_clouds", "set_metrics"]
