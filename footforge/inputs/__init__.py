"""What footforge reads: robot and foot descriptions (xacro, URDF, ROS packages), their checks and
repairs, the foot's sidecar, the variant parameter file, and typed YAML."""
