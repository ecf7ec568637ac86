//! Built-in simulation: world, FPV renderer, multirotor kinematics and a MAVLink vehicle endpoint.
