"""What a scene may say but no model reads yet: refused by name before anything is written."""

from __future__ import annotations

from plantgrowth.base.errors import SceneError
from plantgrowth.scene import Scene


def refuse_fibres(scene: Scene, source: str = "", compare: bool = False) -> None:
    """SceneError if the scene has a fibre director (fibred walls, ``walls.fibre_stiffness``
    other than the constant 0, or ``[feedback]``) where no model reads it yet: the micro model
    (``model = "micro"`` or ``"both"``) and ``plantgrowth compare`` (``compare``). A run stops
    here, after the scene's values are checked and before anything is written. ``source``
    (e.g. a sweep's run) is appended to the message."""
    if scene.has_director and (compare or scene.model != "macro"):
        key = "feedback" if scene.feedback is not None else "walls.fibre_stiffness"
        where = "plantgrowth compare" if compare else f'model = "{scene.model}"'
        raise SceneError(
            f"{key}: fibre-reinforced walls and their feedback are not yet supported by the "
            f'micro model ({where}): run model = "macro", or remove [feedback], and remove '
            f"[walls] or set walls.fibre_stiffness = 0, to run the paper's isotropic "
            f"walls{source}"
        )
