"""The simulated world: quadrotor dynamics, the moving platform, wind, sensors, camera rendering and the
touchdown judge. It never imports the pipeline (see README.md in this folder)."""
