"""The tracked hand: capsule colliders (``HandCapsules``) and their kinematics."""

from sphri._lazy import lazy_exports

# Lazy, like the other packages: importing it (e.g. for its config schema) imports no module until a name is used.
__getattr__, __all__ = lazy_exports(
    "sphri.hand",
    {
        "capsule_segments": "sphri.hand.kinematics",
        "invalid_quaternions": "sphri.hand.kinematics",
        "quat_to_matrix": "sphri.hand.kinematics",
        "repair_quaternions": "sphri.hand.kinematics",
        "rotate_vectors": "sphri.hand.kinematics",
        "validate_quaternions": "sphri.hand.kinematics",
    },
)
