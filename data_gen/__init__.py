"""Synthetic two-view data with exact ground truth (installed as ``ppo_cv.data_gen``)."""

from .protocol import PAPER_K, PAPER_T_MAX, ProtocolSample, euler_to_matrix, paper_protocol

__all__ = [
    "PAPER_K",
    "PAPER_T_MAX",
    "ProtocolSample",
    "euler_to_matrix",
    "paper_protocol",
]
