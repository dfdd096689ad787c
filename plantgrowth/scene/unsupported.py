"""What a scene may say but no model reads yet: refused by name before anything is written."""

from __future__ import annotations

from plantgrowth.base.errors import SceneError
from plantgrowth.scene import Scene


def refuse_fibres(scene: Scene, source: str = "", compare: bool = False) -> None:
    """SceneError if the scene has a fibre director (fibred walls, ``walls.fibre_stiffness``
    other than the constant 0, or ``[feedback]``) where nothing reads it yet: ``plantgrowth
    compare`` (``compare``; the macro and micro models each run fibred scenes). A run stops
    here, after the scene's values are checked and before anything is written. ``source``
    (e.g. a sweep's run) is appended to the message."""
    if scene.has_director and compare:
        key = "feedback" if scene.feedback is not None else "walls.fibre_stiffness"
        raise SceneError(
            f"{key}: fibre-reinforced walls and their feedback are not yet supported by "
            f'plantgrowth compare: run model = "both" to run the macro and micro models side '
            f"by side, or remove [feedback], and remove [walls] or set walls.fibre_stiffness "
            f"= 0, to compare the paper's isotropic walls{source}"
        )
