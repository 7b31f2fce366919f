"""driveid.models."""
