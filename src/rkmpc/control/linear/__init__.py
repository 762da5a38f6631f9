"""Linear MPCs on the kinematic bicycle model: the paper's MPC1 and the identified variant."""
