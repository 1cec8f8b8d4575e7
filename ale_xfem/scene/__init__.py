"""The scene: a TOML file validated strictly (``schema``), ``--set`` overrides, and the
effects it switches on (``effects``).  The names users need are here."""

from ale_xfem.scene.schema import (BoundarySpec, Numerics, Scene, SceneError, load_scene, resolve_scene_path,
                                   shipped_scenes, validate)

__all__ = ["BoundarySpec", "Numerics", "Scene", "SceneError", "load_scene", "resolve_scene_path",
           "shipped_scenes", "validate"]
