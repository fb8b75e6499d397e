"""The eigenmodes of a scene's mechanism at its assembled start: the scene file is read
(scene.py) and its system linearised there (linear.py ``mechanism_modes``); what
``sidprep linearize`` runs and a user's script calls."""

from __future__ import annotations

from dataclasses import dataclass

from sidprep.errors import InputError
from sidprep.solver.linear import MechanismModes, mechanism_modes
from sidprep.solver.scene import Scene, load_scene
from sidprep.tables import require_toml


@dataclass(frozen=True)
class SceneModes:
    """A scene (its title, system and settings) and the MechanismModes of its assembled start."""

    scene: Scene
    modes: MechanismModes


def linearize_scene(path) -> SceneModes:
    """Read the scene file ``path`` (TOML, docs/scenes.md) and return the eigenmodes of its mechanism
    at the assembled start; a floating-frame scene only (bodies and joints)."""
    require_toml(path, "scene file", "linearize takes a scene (docs/scenes.md)")
    scene = load_scene(path)
    if not hasattr(scene.system, "bodies") or not hasattr(scene.system, "joints"):
        raise InputError(f"{path}: linearize needs a floating-frame scene (bodies and joints), "
                         "not an absolute-nodal one")
    return SceneModes(scene, mechanism_modes(scene.system))
