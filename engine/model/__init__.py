"""The skeleton model: motions (BVH-like takes), rotations, forward kinematics, joint roles and the hand's side."""
