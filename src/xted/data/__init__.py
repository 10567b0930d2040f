"""Datasets of episodes: the in-memory type, file formats, windows and normalisation."""

from xted.data.dataset import Dataset, check_dimensions, split_heldout
from xted.data.formats import load, save
from xted.data.normalizer import Normalizer

__all__ = ["Dataset", "Normalizer", "check_dimensions", "load", "save", "split_heldout"]
