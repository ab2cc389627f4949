#!/usr/bin/env python3
"""Derive the ``<inertial>`` elements of ``urdf/anymal_c.urdf.xacro`` from the published listing.

The reference sheet (ANYbotics' public "ANYmal C simple description", BSD-3-Clause, as compiled by
MuJoCo with fixed joints fused) gives, for every moving body, its mass, centre of mass ``ipos``,
principal axes ``iquat`` (w x y z) and principal moments ``inertia``, all in the fused body frame.
Our description puts exactly these fused inertials on the moving links (``base``, ``{leg}_HIP``,
``{leg}_THIGH``, ``{leg}_SHANK``), whose URDF frames coincide with the fused body frames.

URDF wants the inertia tensor about the COM in the link frame, so for each body:

1. normalise ``iquat`` (the listing rounds it to 5 decimals, so its norm is 1 +- 1e-5);
2. ``R`` = rotation matrix of the normalised quaternion (columns = principal axes in the body frame);
3. ``I = R @ diag(inertia) @ R.T`` (symmetric by construction, same eigenvalues as listed);
4. write mass, ``ipos`` as ``<origin xyz>`` with ``rpy="0 0 0"``, and the six independent entries
   ``ixx ixy ixz iyy iyz izz`` with 10 significant digits.

The listing's own precision is about 5 significant digits; the extra digits only make the written
tensor reproduce the listed moments and axes exactly, they add no information.

Usage::

    python derive_inertials.py           # print the <inertial> blocks to paste into the xacro
    python derive_inertials.py --check   # verify the xacro still holds exactly these numbers

Run once when the description was written; kept so that the numbers are reproducible.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

#: Fused rigid bodies of the reference listing: mass [kg], ipos [m], iquat (w x y z),
#: principal moments [kg m^2]. Copied verbatim (5-digit rounding as published).
FUSED_INERTIALS: dict[str, dict[str, tuple[float, ...] | float]] = {
    "base": dict(
        mass=26.37317,
        ipos=(-0.01779, -0.00018, 0.0085),
        iquat=(-0.00383, 0.71958, -0.00775, 0.69436),
        inertia=(1.83725, 1.78446, 0.21386),
    ),
    "LF_HIP": dict(
        mass=2.78100,
        ipos=(0.05666, -0.01529, -0.0083),
        iquat=(-0.12798, 0.70978, -0.13528, 0.67936),
        inertia=(0.00586, 0.00492, 0.00329),
    ),
    "LF_THIGH": dict(
        mass=3.07100,
        ipos=(0.03081, 0.00005, -0.2457),
        iquat=(0.99317, -0.00515, -0.08066, 0.0842),
        inertia=(0.03025, 0.02989, 0.00418),
    ),
    "LF_SHANK": dict(
        mass=0.58842,
        ipos=(0.00546, -0.06125, -0.08066),
        iquat=(0.99293, -0.1159, -0.00105, -0.02544),
        inertia=(0.01016, 0.00924, 0.00112),
    ),
    "RF_HIP": dict(
        mass=2.78100,
        ipos=(0.05676, 0.01529, -0.0083),
        iquat=(0.13524, 0.67907, 0.12798, 0.71006),
        inertia=(0.00586, 0.00492, 0.00329),
    ),
    "RF_THIGH": dict(
        mass=3.07100,
        ipos=(0.03081, 0.00005, -0.2457),
        iquat=(0.99277, -0.00513, -0.08067, 0.08868),
        inertia=(0.03025, 0.02989, 0.00418),
    ),
    "RF_SHANK": dict(
        mass=0.58842,
        ipos=(0.00546, 0.06125, -0.08066),
        iquat=(0.99293, 0.1159, -0.00105, 0.02544),
        inertia=(0.01016, 0.00924, 0.00112),
    ),
    "LH_HIP": dict(
        mass=2.78100,
        ipos=(0.05676, 0.01529, -0.0083),
        iquat=(0.13524, 0.67907, 0.12798, 0.71006),
        inertia=(0.00586, 0.00492, 0.00329),
    ),
    "LH_THIGH": dict(
        mass=3.07100,
        ipos=(0.03081, 0.00005, -0.2457),
        iquat=(0.99277, -0.00513, -0.08067, 0.08868),
        inertia=(0.03025, 0.02989, 0.00418),
    ),
    "LH_SHANK": dict(
        mass=0.58842,
        ipos=(0.00546, 0.06125, -0.08066),
        iquat=(0.99293, 0.1159, -0.00105, 0.02544),
        inertia=(0.01016, 0.00924, 0.00112),
    ),
    "RH_HIP": dict(
        mass=2.78100,
        ipos=(0.05666, -0.01529, -0.0083),
        iquat=(-0.12798, 0.70978, -0.13528, 0.67936),
        inertia=(0.00586, 0.00492, 0.00329),
    ),
    "RH_THIGH": dict(
        mass=3.07100,
        ipos=(0.03081, 0.00005, -0.2457),
        iquat=(0.99317, -0.00515, -0.08066, 0.0842),
        inertia=(0.03025, 0.02989, 0.00418),
    ),
    "RH_SHANK": dict(
        mass=0.58842,
        ipos=(0.00546, -0.06125, -0.08066),
        iquat=(0.99293, -0.1159, -0.00105, -0.02544),
        inertia=(0.01016, 0.00924, 0.00112),
    ),
}

XACRO = Path(__file__).resolve().parent / "urdf" / "anymal_c.urdf.xacro"
SIGNIFICANT_DIGITS = 10


def quat_to_matrix(quat: tuple[float, ...]) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z); the quaternion is normalised first.

    Args:
        quat: quaternion, scalar first; need not be exactly unit length.

    Returns:
        3x3 rotation matrix whose columns are the rotated x, y, z axes.
    """
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def inertia_tensor(iquat: tuple[float, ...], moments: tuple[float, ...]) -> np.ndarray:
    """Inertia tensor about the COM in the body frame: ``R diag(moments) R^T``.

    Args:
        iquat: principal axes as a quaternion (w, x, y, z) in the body frame.
        moments: principal moments of inertia [kg m^2], in the order of the axes of ``iquat``.

    Returns:
        Symmetric 3x3 tensor [kg m^2].
    """
    rot = quat_to_matrix(iquat)
    tensor = rot @ np.diag(moments) @ rot.T
    return 0.5 * (tensor + tensor.T)


def _fmt(value: float) -> str:
    text = f"{value:.{SIGNIFICANT_DIGITS}g}"
    return "0" if text in ("0", "-0") else text


def inertial_values(body: str) -> dict[str, float]:
    """The URDF inertial attributes of one fused body, as numbers (not yet formatted)."""
    data = FUSED_INERTIALS[body]
    tensor = inertia_tensor(data["iquat"], data["inertia"])
    values = {"mass": float(data["mass"])}
    values.update(zip(("x", "y", "z"), map(float, data["ipos"])))
    for key, (i, j) in dict(ixx=(0, 0), ixy=(0, 1), ixz=(0, 2), iyy=(1, 1), iyz=(1, 2), izz=(2, 2)).items():
        values[key] = float(tensor[i, j])
    return values


def inertial_xml(body: str, indent: str = "    ") -> str:
    """The ``<inertial>`` element of one body, formatted as it appears in the xacro."""
    v = {k: _fmt(x) for k, x in inertial_values(body).items()}
    return (
        f"{indent}<!-- {body}: fused inertial (derive_inertials.py) -->\n"
        f"{indent}<inertial>\n"
        f'{indent}  <mass value="{v["mass"]}"/>\n'
        f'{indent}  <origin xyz="{v["x"]} {v["y"]} {v["z"]}" rpy="0 0 0"/>\n'
        f'{indent}  <inertia ixx="{v["ixx"]}" ixy="{v["ixy"]}" ixz="{v["ixz"]}"\n'
        f'{indent}           iyy="{v["iyy"]}" iyz="{v["iyz"]}" izz="{v["izz"]}"/>\n'
        f"{indent}</inertial>"
    )


def check_xacro(path: Path = XACRO) -> list[str]:
    """Compare the inertial blocks written in the xacro with the derived ones.

    The xacro marks each block with a ``<!-- BODY: fused inertial ... -->`` comment followed by the
    ``<inertial>`` element; this function finds them by that comment.

    Args:
        path: the xacro file.

    Returns:
        A list of human-readable mismatches; empty when every body matches.
    """
    text = path.read_text()
    problems = []
    for body in FUSED_INERTIALS:
        match = re.search(rf"<!-- {body}: fused inertial.*?-->\s*(<inertial>.*?</inertial>)", text, flags=re.S)
        if match is None:
            problems.append(f"{body}: no inertial block found")
            continue
        block = match.group(1)
        numbers = {
            k: float(x)
            for k, x in re.findall(r'(\w+)="([^"]+)"', block)
            if k in ("value", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        }
        numbers["mass"] = numbers.pop("value")
        xyz = re.search(r'xyz="([^"]+)"', block).group(1).split()
        numbers.update(zip(("x", "y", "z"), map(float, xyz)))
        for key, expected in inertial_values(body).items():
            if abs(numbers[key] - expected) > 1e-9 * max(1.0, abs(expected)):
                problems.append(f"{body}.{key}: xacro {numbers[key]!r} != derived {expected!r}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="verify the xacro's inertials instead of printing them")
    args = parser.parse_args(argv)
    if args.check:
        problems = check_xacro()
        for line in problems:
            print(line, file=sys.stderr)
        print("ok" if not problems else f"{len(problems)} mismatch(es)")
        return 1 if problems else 0
    for body in FUSED_INERTIALS:
        print(inertial_xml(body))
    total = sum(float(d["mass"]) for d in FUSED_INERTIALS.values())
    print(f"<!-- total mass {total:.5f} kg -->")
    return 0


if __name__ == "__main__":
    sys.exit(main())
