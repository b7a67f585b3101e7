"""Geometry on skeletons and meshes, above the core: self-collision detection (BVH, exact triangle
tests), the interpenetration energy and metrics, foot and hand contact detection and the mesh
correspondence that carries contacts between characters, and inverse kinematics."""
