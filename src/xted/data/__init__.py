"""Datasets of episodes: the in-memory type, file formats, windows and normalisation."""

from xted.data.dataset import Dataset
from xted.data.formats import load, save
from xted.data.normalizer import Normalizer
from xted.data.windows import Windows, make_windows

__all__ = ["Dataset", "Normalizer", "Windows", "load", "make_windows", "save"]
