"""Measuring edits: a learned dynamics proxy (the paper's measure) and task-content similarity."""

from xted.analysis.content import content_similarity
from xted.analysis.proxy import DynamicsProxy, ProxyConfig, fit_proxy

__all__ = ["DynamicsProxy", "ProxyConfig", "content_similarity", "fit_proxy"]
