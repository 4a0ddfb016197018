"""Exporting a trained policy: ``smartcar-export`` writes it as ONNX (``onnx_graph``,
``cli``), to be run without torch by ``smartcar_gym.runtime``. Needs the ``train`` and
``onnx`` extras. (``smartcar_gym.agents.export`` packages a run as a shipped policy.)
"""
