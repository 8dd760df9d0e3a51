"""A fitted model at work outside the process that made it: the model file (save, load) and predictions."""

from torchpaml._model.file import load_model, save_model
from torchpaml._model.prediction import Prediction, predict

__all__ = ["Prediction", "load_model", "predict", "save_model"]
