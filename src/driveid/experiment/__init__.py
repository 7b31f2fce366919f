"""Experiment protocols that drive a plant: PHO campaigns, excitation runs, plant adapters."""

from driveid.experiment.excitation import (
    ExcitablePlant,
    ExcitationRuns,
    SimulatedExcitationPlant,
    run_excitations,
)
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
    "ExcitablePlant",
    "SimulatedExcitationPlant",
    "ExcitationRuns",
    "run_excitations",
]
