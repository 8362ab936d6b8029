"""The learner of paper §2-3: SRV units over a BOXES memory, generalized then specialized."""

from forcelearn.learning.boxes import BoxGrid, BoxRangeError, Dimension, neighbourhood_kernel
from forcelearn.learning.exploration import AffineOutput, IdentityOutput, sigma_of_prediction
from forcelearn.learning.params import SRVParams
from forcelearn.learning.phase import Phase, PhaseSchedule
from forcelearn.learning.srv import Action, SRVLearner
from forcelearn.learning.state_file import load_extra_arrays, load_learner, save_learner

__all__ = [
    "Action",
    "AffineOutput",
    "BoxGrid",
    "BoxRangeError",
    "Dimension",
    "IdentityOutput",
    "Phase",
    "PhaseSchedule",
    "SRVLearner",
    "SRVParams",
    "load_extra_arrays",
    "load_learner",
    "neighbourhood_kernel",
    "save_learner",
    "sigma_of_prediction",
]
