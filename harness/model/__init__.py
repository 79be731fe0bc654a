"""The robot: its description (TOML, URDF), inertia, friction, kinematics, regressor, export."""
