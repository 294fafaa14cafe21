"""ppo-cv: relative pose of two calibrated views by the pose-only (PPO) inequalities.

``recoverPose`` is a drop-in for ``cv2.recoverPose``; ``recover_pose`` returns a
:class:`PoseResult` with the pure-rotation decision and analytic 3D points. The paper's math
lives in :mod:`ppo_cv.ppo`.
"""

from .opencv_compat import install, installed, is_installed, recoverPose, uninstall
from .pose import PoseResult, recover_pose
from .ppo import DEFAULT_PRI_THRESHOLD

__all__ = [
    "DEFAULT_PRI_THRESHOLD",
    "PoseResult",
    "install",
    "installed",
    "is_installed",
    "recoverPose",
    "recover_pose",
    "uninstall",
]

__version__ = "0.1.0"
