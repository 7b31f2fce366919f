"""driveid.sim."""
