"""The domain core, the bottom layer: rotations, forward kinematics, skeletons and the canonical 22
joints, motions, skinned characters, linear blend skinning, the rest-pose transfer that defines
the ground truth, and a character's heights and rest ground (:mod:`.measures`). It imports nothing
else of the library; everything else builds on it."""
