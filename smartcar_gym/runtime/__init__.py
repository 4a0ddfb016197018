"""Running an exported policy without torch: ``smartcar-export``'s ONNX files.

* ``onnx_file``: reads an ONNX model's protobuf with the standard library and numpy.
* ``numpy_graph``: evaluates the graph's operators (those of an MLP policy) with numpy.
* ``metadata``: the env id, kwargs, engine and observation names an exported policy carries.
* ``onnx_policy``: ``load_onnx(path)``, a model with SB3's ``predict`` run by onnxruntime
  (the ``onnx`` extra) where installed, else by ``numpy_graph``.

``smartcar_gym.policy.Policy.load("policy.onnx")`` is the way in; nothing here imports torch,
Stable-Baselines3 or the ``onnx`` package.
"""
