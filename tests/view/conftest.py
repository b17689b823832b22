"""Shared pieces of the viewer tests: small URDFs written into tmp_path."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LITE_URDF = REPO / "examples" / "lite" / "lite_bimanual.urdf"

TWO_JOINT = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="upper"><visual><origin xyz="0 0 0.1"/><geometry><box size="0.02 0.02 0.2"/></geometry></visual></link>
  <link name="lower"><visual><geometry><cylinder radius="0.01" length="0.2"/></geometry></visual></link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="1" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.2" rpy="0 0.3 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="0.5" effort="1" velocity="1"/>
  </joint>
</robot>
"""


@pytest.fixture
def two_joint_urdf(tmp_path: Path) -> Path:
    p = tmp_path / "two.urdf"
    p.write_text(TWO_JOINT)
    return p
