r"""The published study of the prototype, reproduced and taken further (``spm demo``).

The study ("Modeling and Simulation of Spherical Parallel Manipulators in CoppeliaSim
(V-REP)") modelled a 3D-printed coaxial SPM, compared the platform axes v_i computed
from its kinematic model with those read from the simulation at the input
theta = [60, 90, 120] deg (they agreed to about 4e-4), showed the motion from home to
that input at 25 samples, and found a link collision at theta = [60, 90, 220] deg.
:func:`run_demo` does all of it on the same prototype and adds what the study left as
future work:

1. forward kinematics at the demonstration input three ways, side by side: the
   analytic closed form (:func:`~spm_pin.forward_kinematics`), Newton projection on the
   Pinocchio model (:meth:`~spm_pin.ClosedLoop.project`, from home) and MuJoCo stepping
   the exported MJCF (:func:`mujoco_platform_axes`);
2. every real assembly mode there, the singularity check (the Jacobian) and the
   inverse-kinematics round trip;
3. the motion from home to the input at 25 samples, analytic
   (:func:`~spm_pin.track`) against projection (:meth:`~spm_pin.ClosedLoop.follow`)
   and MuJoCo, with a plot of the x, y, z components of v_1, v_2, v_3;
4. the colliding input: the colliding link pairs (:func:`spm_pin.collision.check_input`,
   which names the assembly mode checked) and a scene with those links in black;
5. the safe workspace over the gaps between the proximal links
   (:func:`spm_pin.workspace.workspace_map`);
6. the actuator torques along the motion (:func:`~spm_pin.inverse_dynamics`) against
   the XM540-W150 servo's torque-speed envelope, with a verdict;
7. an HTML report (``index.html``, PNG plots beside it and meshcat scenes in iframes,
   every file self-contained, so the folder works offline), with a PNG picture of
   each scene made in a headless Chromium when Playwright and a Chromium are there,
   and ``demo.json``.

MuJoCo, matplotlib and meshcat are optional (the ``demo`` extra): without one of them
the demo runs everything else and lists what it skipped and what to install.

Why MuJoCo differs from the other two: its loop-closing welds are soft constraints
(a spring-damper per weld). With the inputs held and no load the welds close exactly
and MuJoCo agrees with the analytic solution to about 1e-13; standing upright, the
welds carry the platform's weight and yield by about 1e-5 (with the stiff settings of
:func:`~spm_pin.simulate_mujoco`; MuJoCo's stock settings would let them open by a
tenth of a radian). The demo reports both runs.

The package holds the study by concept: ``context`` (the settings, :class:`DemoContext`
and the section and result types), ``sections`` (:data:`DEMO_SECTIONS`), ``mujoco``
(the MuJoCo cross-check), ``plots``, ``report`` (``index.html`` and the text output),
``pictures`` (the scenes' pictures), ``run`` (:func:`run_demo`) and ``_extras`` (the
optional dependencies).
"""

from __future__ import annotations

from ._extras import INSTALL_DEMO, OPTIONAL_DEPENDENCIES, Skipped
from .context import (
    DEMO_COLLIDING_THETA_DEG,
    DEMO_SAMPLES,
    DEMO_THETA_DEG,
    MUJOCO_TOLERANCE,
    PROJECTION_TOLERANCE,
    STUDY_AGREEMENT,
    DemoContext,
    DemoResult,
    DemoSection,
    ReportItem,
)
from .mujoco import MUJOCO_PASSIVE_DAMPING as MUJOCO_PASSIVE_DAMPING
from .mujoco import MUJOCO_SETTLE_STEPS, MUJOCO_TIMESTEP, MujocoAxes, mujoco_platform_axes
from .run import ProgressMode as ProgressMode
from .run import demo_record, run_demo
from .sections import DEMO_SECTIONS

__all__ = [
    "DEMO_COLLIDING_THETA_DEG",
    "DEMO_SAMPLES",
    "DEMO_SECTIONS",
    "DEMO_THETA_DEG",
    "INSTALL_DEMO",
    "MUJOCO_SETTLE_STEPS",
    "MUJOCO_TIMESTEP",
    "MUJOCO_TOLERANCE",
    "OPTIONAL_DEPENDENCIES",
    "PROJECTION_TOLERANCE",
    "STUDY_AGREEMENT",
    "DemoContext",
    "DemoResult",
    "DemoSection",
    "MujocoAxes",
    "ReportItem",
    "Skipped",
    "demo_record",
    "mujoco_platform_axes",
    "run_demo",
]
