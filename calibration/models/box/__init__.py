"""Extended box-type carbody model (seed rtri-carbody-box-model-pso, section 2)."""
from .assembly import BoxModel, BoxVehicle, assemble
from .shinkansen import FACTOR_SETS, SEARCH_PARAMETERS, FactorSet, factor_set, free_carbody, shinkansen_vehicle

__all__ = ["BoxModel", "BoxVehicle", "assemble", "FACTOR_SETS", "FactorSet", "SEARCH_PARAMETERS", "factor_set",
           "free_carbody", "shinkansen_vehicle"]
