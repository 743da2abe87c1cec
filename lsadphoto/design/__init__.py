"""The inverse problem: choose luminaires and their layout for a given lighting quality.

Each candidate luminaire is simulated once; a design's maps and grids are the weighted sum
of its candidates' solutions (:mod:`~lsadphoto.design.superposition`).
"""

from .superposition import CandidateSolution, solve_candidate, superpose

__all__ = ["CandidateSolution", "solve_candidate", "superpose"]
