"""The tracked hand: capsule colliders (``HandCapsules``) and their kinematics."""

from sphri.hand.kinematics import (
    capsule_segments,
    invalid_quaternions,
    quat_to_matrix,
    repair_quaternions,
    rotate_vectors,
    validate_quaternions,
)

__all__ = [
    "capsule_segments",
    "invalid_quaternions",
    "quat_to_matrix",
    "repair_quaternions",
    "rotate_vectors",
    "validate_quaternions",
]
