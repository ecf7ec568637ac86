//! Role implementations: camera, perception, reasoning planner, controller, simulated vehicle.
