"""Bundled robot descriptions: one folder per robot with its URDF, robot.toml, task and README."""
