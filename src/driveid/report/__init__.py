"""driveid.report."""
