"""Everything footforge authors with dm_control.mjcf: elements from a Pinocchio parse, the feet
(closed chain, AFF, AOF), the robot, the drop-test rig, the scene, and writing them out."""
