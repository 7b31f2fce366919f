"""driveid.experiment."""
