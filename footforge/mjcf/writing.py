"""MJCF roots to files and compiled models: text whose assets live in assets/, and MjModels."""

from __future__ import annotations

import mujoco
from dm_control import mjcf
from lxml import etree


def xml_with_assets(root: mjcf.RootElement, asset_sets: list[dict]) -> str:
    """MJCF text whose asset files (content-hashed names from dm_control) live in assets/."""
    tree = etree.fromstring(root.to_xml_string().encode())
    compiler = tree.find("compiler")
    if compiler is None:
        compiler = etree.Element("compiler")
        tree.insert(0, compiler)
    # dm_control resolves asset paths itself and does not write meshdir; MuJoCo needs it on disk.
    compiler.set("meshdir", "assets")
    compiler.set("texturedir", "assets")
    asset_sets.append(root.get_assets())
    return etree.tostring(tree, pretty_print=True, encoding="unicode")


def compile_model(root: mjcf.RootElement) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), assets=root.get_assets())
