"""Generated MuJoCo XML with longer or shorter thighs.

Each thigh's capsule (its centre offset and half-length) is scaled by the factor; the child
body (the shin) moves with the thigh's far end, so the leg stays attached at the new knee;
the torso is raised (or lowered) by the thighs' added vertical extent so the robot starts
standing just as high above the floor as before.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

THIGH_BODIES = {"halfcheetah": ("bthigh", "fthigh"), "walker2d": ("thigh", "thigh_left"), "hopper": ("thigh",)}


def _vec(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split()])


def _fmt(values: np.ndarray) -> str:
    return " ".join(f"{v:.10g}" for v in values)


def scaled_thigh_xml(env: str, source_xml: str | Path, factor: float) -> tuple[str, float]:
    """Return (XML text with thighs scaled by ``factor``, torso height change in metres)."""
    tree = ET.parse(source_xml)
    root = tree.getroot()
    bodies = {b.get("name"): b for b in root.iter("body")}
    lift = -np.inf
    for name in THIGH_BODIES[env]:
        thigh = bodies[name]
        geom = thigh.find("geom")
        centre = _vec(geom.get("pos", "0 0 0"))
        size = _vec(geom.get("size"))
        size[1] *= factor
        geom.set("size", _fmt(size))
        geom.set("pos", _fmt(centre * factor))
        # The capsule runs from the hip joint to the knee, so the knee sits at about 2x its centre.
        knee_shift = 2.0 * centre * (factor - 1.0)
        child = thigh.find("body")
        child.set("pos", _fmt(_vec(child.get("pos")) + knee_shift))
        lift = max(lift, -knee_shift[2])
    torso = bodies["torso"]
    torso_pos = _vec(torso.get("pos"))
    torso_pos[2] += lift
    torso.set("pos", _fmt(torso_pos))
    for joint in torso.findall("joint"):
        if joint.get("name") == "rootz" and joint.get("ref") is not None:
            joint.set("ref", f"{float(joint.get('ref')) + lift:.10g}")
    return ET.tostring(root, encoding="unicode"), lift
