"""Global optimisers behind one call shape: ``optimiser(objective, parameters, rng, settings=...)``."""
from .base import SearchParameter
from .cross_entropy import CESettings, cross_entropy
from .pso import PSOSettings, particle_swarm

OPTIMISERS = {"ce": (cross_entropy, CESettings), "pso": (particle_swarm, PSOSettings)}

__all__ = ["OPTIMISERS", "SearchParameter", "CESettings", "PSOSettings", "cross_entropy", "particle_swarm"]
