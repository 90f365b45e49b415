"""Plants: what happens to the joint-velocity command between the controller and the arm."""

from otmm_qp.plants.chain import PlantChain, build_plant, plant_label
from otmm_qp.plants.delay import DelayPlant
from otmm_qp.plants.ideal import IdealPlant
from otmm_qp.plants.lag import LagPlant
from otmm_qp.plants.plant import Plant, PlantStep
from otmm_qp.plants.rate_limit import RateLimitPlant
from otmm_qp.plants.sensor import SensorPlant

__all__ = [
    "DelayPlant",
    "IdealPlant",
    "LagPlant",
    "Plant",
    "PlantChain",
    "PlantStep",
    "RateLimitPlant",
    "SensorPlant",
    "build_plant",
    "plant_label",
]
