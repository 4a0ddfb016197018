"""The MuJoCo engine behind the simulator facade (the ``mujoco`` extra).

``model`` builds the ``MjSpec`` of one robot from its URDF (reusable for batched worlds),
``simulator`` is ``MujocoSimulator`` (the clock, stepping, the world's spec, model and data),
``body`` the ``Body`` handles and the visual-only markers, ``render`` the offscreen camera.
Importing this package imports ``mujoco``.
"""
