"""Physics of the descriptions, before any MJCF: the kinematic tree as Pinocchio parses it, the
closed chain's reference pose, convex decomposition of collision meshes, the foot source every
variant derives from, and mass properties of compiled models."""
