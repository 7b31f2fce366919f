"""Experiment protocols that drive a plant: PHO campaigns and the plant adapters."""

from driveid.experiment.pho import (
    Campaign,
    CampaignRun,
    RunAssessment,
    assess_run,
    run_pho_campaign,
    settle_time,
)
from driveid.experiment.plant import LoopbackPlant, Plant, SimulatedPlant

__all__ = [
    "Plant",
    "SimulatedPlant",
    "LoopbackPlant",
    "Campaign",
    "CampaignRun",
    "RunAssessment",
    "assess_run",
    "run_pho_campaign",
    "settle_time",
]
