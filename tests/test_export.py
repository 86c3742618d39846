"""Robot files: the committed prototype files, Pinocchio and MuJoCo loading them, ``spm export``."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import trimesh
from conftest import general_design

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.model.export import END_BODIES, JOINT_NAMES, MJCF_NAME, URDF_NAME, export
from spm_pin.model.geometry import LINK_NAMES, link_inertias, link_meshes

#: The committed prototype files (urdf/, see urdf/README.md).
URDF_DIR = Path(__file__).resolve().parents[1] / "urdf"

#: Tolerances, by what they compare.
TOL = {
    "axis": 1e-11,  # a joint axis read back from a file (12 significant digits)
    "inertia": 1e-11,  # mass properties read back from a file (12 significant digits, relative)
    "stl": 1e-6,  # STL vertices are float32 [m]
}


@pytest.fixture(scope="module")
def prototype_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return export(spm.SPMDesign.prototype(), tmp_path_factory.mktemp("export"))


def _design_axes(design: spm.SPMDesign) -> dict[str, np.ndarray]:
    axes = {"u": design.u, "w": design.w0, "v": design.v0}
    return {f"{name[0]}_{name[2]}": axes[name[0]][int(name[2]) - 1] for name in JOINT_NAMES}


def _world_axes(model: pin.Model) -> dict[str, np.ndarray]:
    """Each joint's world axis at home, measured: turn that joint alone and read log3."""
    data = model.createData()
    axes = {}
    for name in JOINT_NAMES:
        joint = model.getJointId(name)
        q = pin.neutral(model)
        q[model.idx_qs[joint]] = 0.5
        pin.forwardKinematics(model, data, q)
        axes[name] = pin.log3(data.oMi[joint].rotation) / 0.5
    return axes


def _check_model(model: pin.Model, design: spm.SPMDesign) -> None:
    assert model.nq == model.nv == 9
    assert tuple(model.names[1:]) == JOINT_NAMES  # q order: u_1, w_1, v_1, u_2, ...
    measured, expected = _world_axes(model), _design_axes(design)
    for name in JOINT_NAMES:
        np.testing.assert_allclose(measured[name], expected[name], atol=TOL["axis"], err_msg=name)
    # Identity joint placements: q = 0 is home, every link frame the world frame.
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    for joint in range(1, model.njoints):
        assert data.oMi[joint].isIdentity(1e-12)
    # Mass properties: the links', the platform's split in thirds over the end bodies.
    inertias = link_inertias(design)
    bodies = {name: model.getFrameId(name) for name in (*LINK_NAMES[1:7], *END_BODIES)}
    for body, frame in bodies.items():
        joint = model.frames[frame].parentJoint
        source = inertias["platform" if body in END_BODIES else body]
        fraction = 1 / 3 if body in END_BODIES else 1.0
        inertia = model.inertias[joint]
        np.testing.assert_allclose(inertia.mass, fraction * source.mass, rtol=TOL["inertia"])
        np.testing.assert_allclose(inertia.lever, source.com, atol=TOL["inertia"])
        scale = fraction * float(np.abs(source.inertia).max())
        np.testing.assert_allclose(
            inertia.inertia, fraction * source.inertia, atol=TOL["inertia"] * scale
        )


# --------------------------------------------------------------- committed files
def test_committed_files_equal_the_generated_ones(prototype_files: dict[str, Path]) -> None:
    """The prototype's files in urdf/ are exactly what the generator makes; regenerate
    them with ``spm export`` after changing the design or the generator."""
    committed = {
        str(p.relative_to(URDF_DIR))
        for p in URDF_DIR.rglob("*")
        if p.suffix in {".urdf", ".xml", ".stl"}
    }
    assert committed == set(prototype_files)
    for relative, path in prototype_files.items():
        assert (URDF_DIR / relative).read_bytes() == path.read_bytes(), (
            f"urdf/{relative} differs from the generator's output: run `spm export`"
        )


def test_export_is_deterministic(tmp_path: Path, prototype_files: dict[str, Path]) -> None:
    again = export(None, tmp_path)
    assert set(again) == set(prototype_files)
    for relative, path in again.items():
        assert path.read_bytes() == prototype_files[relative].read_bytes(), relative


def test_meshes_read_back(prototype_files: dict[str, Path]) -> None:
    meshes = link_meshes()
    for name in LINK_NAMES:
        loaded = trimesh.load_mesh(prototype_files[f"meshes/{name}.stl"])
        assert len(loaded.faces) == len(meshes[name].faces)
        assert loaded.is_watertight, name
        np.testing.assert_allclose(loaded.bounds, meshes[name].bounds, atol=TOL["stl"])
        np.testing.assert_allclose(loaded.volume, meshes[name].volume, rtol=1e-5)


# ------------------------------------------------------------------------- loaders
@pytest.mark.parametrize("make", [spm.SPMDesign.prototype, general_design])
def test_pinocchio_reads_the_urdf(tmp_path: Path, make: type[spm.SPMDesign]) -> None:
    design = make()
    files = export(design, tmp_path)
    model = pin.buildModelFromUrdf(str(files[URDF_NAME]))
    _check_model(model, design)
    geometry = pin.buildGeomFromUrdf(
        model, str(files[URDF_NAME]), pin.GeometryType.COLLISION, package_dirs=[str(tmp_path)]
    )
    assert geometry.ngeoms == len(LINK_NAMES)


@pytest.mark.parametrize("make", [spm.SPMDesign.prototype, general_design])
def test_pinocchio_reads_the_mjcf_with_two_closures(
    tmp_path: Path, make: type[spm.SPMDesign]
) -> None:
    design = make()
    path = str(export(design, tmp_path)[MJCF_NAME])
    model, point_anchors, frame_anchors = pin.buildModelAndConstraintsFromMJCF(path)
    _check_model(model, design)
    assert len(point_anchors) == 0
    assert len(frame_anchors) == 2
    platform_joint = model.frames[model.getFrameId("platform")].parentJoint
    ends = {model.frames[model.getFrameId(b)].parentJoint for b in END_BODIES[1:]}
    for weld in frame_anchors:
        assert {weld.joint1_id, weld.joint2_id} & ends
        assert platform_joint in {weld.joint1_id, weld.joint2_id}
        assert weld.joint1_placement.isIdentity() and weld.joint2_placement.isIdentity()
    # The mesh geoms are collision geometry too (nonzero contype/conaffinity).
    collision = pin.buildGeomFromMJCF(model, path, pin.GeometryType.COLLISION)
    assert sorted(g.name for g in collision.geometryObjects) == sorted(LINK_NAMES)


def test_mujoco_loads_the_mjcf(prototype_files: dict[str, Path]) -> None:
    model = mujoco.MjModel.from_xml_path(str(prototype_files[MJCF_NAME]))
    assert model.nq == 9
    assert [model.joint(i).name for i in range(model.njnt)] == list(JOINT_NAMES)
    assert model.neq == 2
    assert model.ngeom == len(LINK_NAMES)
    inertias = link_inertias()
    total = sum(i.mass for i in inertias.values())
    np.testing.assert_allclose(model.body_mass.sum(), total, rtol=TOL["inertia"])
    # No contacts between the robot's own geoms, wherever the joints are.
    data = mujoco.MjData(model)
    data.qpos[:] = np.radians([60, 20, -10, 90, 0, 30, 120, 10, 0])
    for _ in range(50):
        mujoco.mj_step(model, data)
    assert data.ncon == 0
    assert np.all(np.isfinite(data.qpos))


# ----------------------------------------------------------------------------- CLI
def test_cli_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "robot"
    assert main(["export", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for relative in (URDF_NAME, MJCF_NAME, *(f"meshes/{n}.stl" for n in LINK_NAMES)):
        assert (out / relative).is_file()
        assert str(out / relative) in printed
        assert (out / relative).read_bytes() == (URDF_DIR / relative).read_bytes()


def test_cli_export_json_with_a_design_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    design_file = spm.SPMDesign.agile_eye().save(tmp_path / "eye.toml")
    out = tmp_path / "eye"
    assert main(["export", "--design", str(design_file), "--out", str(out), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["design"] == "agile_eye"
    assert len(record["files"]) == 2 + len(LINK_NAMES)
    assert all(Path(f).is_file() for f in record["files"])


def test_cli_export_bad_design_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[kinematics]\nalpha1_deg = 45\n", encoding="utf-8")
    assert main(["export", "--design", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("spm: error: ") and err.count("\n") == 1
    assert not (tmp_path / "out").exists()
    assert main(["export", "--design", str(tmp_path / "missing.toml")]) == 2
