"""The ground every footforge model stands on: a checkered floor and a light, and scene.xml,
which includes the robot file beside them (MuJoCo Menagerie's layout)."""

from __future__ import annotations

from dm_control import mjcf
from lxml import etree

FLOOR_CONTYPE = 1  # environment geoms touch robot collision geoms (conaffinity 1)


def add_floor(root: mjcf.RootElement) -> None:
    grid = root.asset.add(
        "texture",
        name="grid",
        type="2d",
        builtin="checker",
        width=512,
        height=512,
        rgb1=[0.2, 0.3, 0.4],
        rgb2=[0.1, 0.2, 0.3],
    )
    material = root.asset.add("material", name="grid", texture=grid, texrepeat=[8, 8], reflectance=0.1)
    root.worldbody.add("light", name="sun", pos=[0, 0, 3], dir=[0, 0, -1], directional=True)
    root.worldbody.add(
        "geom", name="floor", type="plane", size=[0, 0, 0.05], material=material, contype=FLOOR_CONTYPE, conaffinity=1
    )


def scene_xml(robot_file: str, variant: str) -> str:
    """scene.xml: the robot file included, plus a floor and a light (MuJoCo Menagerie's layout)."""
    root = mjcf.RootElement(model=f"anymal_c_{variant}_scene")
    add_floor(root)
    root.visual.headlight.set_attributes(diffuse=[0.6, 0.6, 0.6], ambient=[0.3, 0.3, 0.3])
    root.statistic.set_attributes(center=[0, 0, 0.3], extent=1.2)
    tree = etree.fromstring(root.to_xml_string().encode())
    for default in tree.findall("default"):  # dm_control's empty top class clashes with the robot's
        tree.remove(default)
    tree.insert(0, etree.Element("include", file=robot_file))
    return etree.tostring(tree, pretty_print=True, encoding="unicode")
