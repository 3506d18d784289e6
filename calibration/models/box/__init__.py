"""Extended box-type carbody model (seed rtri-carbody-box-model-pso, section 2)."""
from .assembly import BoxModel, BoxVehicle, assemble
from .shinkansen import SEARCH_PARAMETERS, free_carbody, shinkansen_vehicle

__all__ = ["BoxModel", "BoxVehicle", "assemble", "SEARCH_PARAMETERS", "free_carbody", "shinkansen_vehicle"]
