"""Choosing the foot's root link in a description that holds more than the foot.

A foot is bolted to the robot's foot mount by its root link. Published descriptions often wrap
the foot in a test rig: a `world` link (MuJoCo reserves that name for its world body), sometimes
a leg link on a floating or sliding joint, then the foot. footforge keeps the subtree of the root
link and drops everything above it, with the joints that connect it:
- the sidecar's `root_link` names the link when given;
- otherwise the URDF's root is used, descending past empty links (no inertial, visual or
  collision, like `world`) that hold a single child by a fixed joint. A rig with a moving joint
  under `world` cannot be guessed: the user is told to set `root_link`.
The links dropped are reported, so nothing disappears silently.
"""

from __future__ import annotations

import difflib
from dataclasses import replace
from pathlib import Path

from lxml import etree

from footforge.errors import InputError
from footforge.inputs.description import Description, descriptions_dir

WORLD_LINK = "world"
"""MuJoCo's world body: a foot's root link cannot have this name."""


def _is_shipped(sidecar_path: Path) -> bool:
    """Whether the sidecar is one of footforge's own (under descriptions/): its user should copy
    it rather than edit it."""
    return Path(sidecar_path).resolve().is_relative_to(descriptions_dir().resolve())


def _is_empty_link(link: etree._Element) -> bool:
    return all(link.find(tag) is None for tag in ("inertial", "visual", "collision"))


def _detect_root(root: etree._Element, description: Description, sidecar_path: Path | None) -> str:
    joints = root.findall("joint")
    children = {j.find("child").get("link") for j in joints}
    links = {e.get("name"): e for e in root.findall("link")}
    tops = [name for name in links if name not in children]
    if len(tops) != 1:
        return tops[0] if tops else ""  # parse_urdf reports a forest or a cycle
    current = tops[0]
    while _is_empty_link(links[current]):
        below = [j for j in joints if j.find("parent").get("link") == current]
        if len(below) != 1:
            break
        if below[0].get("type") != "fixed":
            if current != WORLD_LINK:
                break
            child = below[0].find("child").get("link")
            where = f"the sidecar {sidecar_path}" if sidecar_path else "the sidecar"
            raise InputError(
                f"the root link '{WORLD_LINK}' holds '{child}' by a {below[0].get('type')} joint "
                f"'{below[0].get('name')}' (a test rig): the foot's own root link cannot be detected",
                file=str(description.source),
                element=f"link '{WORLD_LINK}'",
                fix=f"set root_link in {where} to the link that the robot's foot mount carries "
                "(the foot's top link); everything above it is dropped",
            )
        current = below[0].find("child").get("link")
    return current


def select_foot_root(
    description: Description, root_link: str | None, *, sidecar_path: Path | None = None
) -> tuple[Description, list[str]]:
    """The description cut to the subtree of the foot's root link, and notes on what was dropped.

    Args:
      root_link: the sidecar's `root_link`, or None to detect it (module docstring).
      sidecar_path: named in the messages that ask the user to set `root_link`.

    Raises:
      InputError: the named link does not exist, is `world`, or the root cannot be detected.
    """
    root = description.root()
    links = [e.get("name") for e in root.findall("link")]
    if not links:  # a file of macros only, e.g. the public package's model/softfoot_thing.urdf.xacro
        raise InputError(
            "the description expands to no links: it only defines xacro macros",
            file=str(description.source),
            element="<robot>",
            fix="pass a file that instantiates the foot (one that calls the macro, such as the "
            "public package's robot/floating_softfoot.urdf.xacro), or write a small xacro that "
            "includes this one and calls its macro",
        )
    if root_link is None:
        chosen = _detect_root(root, description, sidecar_path)
    else:
        chosen = root_link
        if chosen not in links:
            near = difflib.get_close_matches(chosen, links, n=3, cutoff=0.5)
            hint = f" (close: {', '.join(near)})" if near else ""
            if sidecar_path and _is_shipped(sidecar_path):
                fix = (
                    f"this sidecar, shipped with footforge, names one foot of a published description; "
                    f"copy {sidecar_path}, set root_link and the other joint and link names to those of "
                    "your file (e.g. another foot's prefix), and pass the copy with --sidecar"
                )
            else:
                fix = (
                    f"set root_link in {sidecar_path or 'the sidecar'} to one of the description's links "
                    "(the one the robot's foot mount carries), or remove the key to detect it"
                )
            raise InputError(
                f"the sidecar's root_link '{chosen}' is not a link of {description.source.name}{hint}",
                file=str(sidecar_path) if sidecar_path else None,
                element="root_link",
                fix=fix,
            )
    if chosen == WORLD_LINK:
        raise InputError(
            f"the foot's root link is '{WORLD_LINK}', the name MuJoCo reserves for its world body",
            file=str(sidecar_path or description.source),
            element="root_link",
            fix=f"set root_link in {sidecar_path or 'the sidecar'} to the foot's top link, below '{WORLD_LINK}'",
        )
    joints = root.findall("joint")
    below: dict[str, list[etree._Element]] = {}
    for j in joints:
        below.setdefault(j.find("parent").get("link"), []).append(j)
    keep, stack = set(), [chosen]
    while stack:
        link = stack.pop()
        if link in keep:
            continue
        keep.add(link)
        stack += [j.find("child").get("link") for j in below.get(link, [])]
    dropped_links = [name for name in links if name not in keep]
    if not dropped_links:
        return description, []
    dropped_joints = []
    for j in joints:
        if j.find("parent").get("link") not in keep or j.find("child").get("link") not in keep:
            dropped_joints.append(j.get("name"))
            root.remove(j)
    for e in root.findall("link"):
        if e.get("name") not in keep:
            root.remove(e)
    for g in root.findall("gazebo"):  # Gazebo extensions of dropped links would name nothing
        if g.get("reference") in dropped_links:
            root.remove(g)
    note = (
        f"root link '{chosen}': dropped {len(dropped_links)} link(s) above or beside it "
        f"({', '.join(dropped_links)}) and joint(s) {', '.join(dropped_joints)}"
    )
    return replace(description, urdf=etree.tostring(root, encoding="unicode")), [note]
