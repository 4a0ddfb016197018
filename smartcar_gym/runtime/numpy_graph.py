"""A numpy evaluator of ONNX graphs made of the operators an MLP policy uses.

``NumpyGraph(model)`` checks every node against ``OPERATORS`` (an unknown one raises
``UnknownOperatorError`` naming it and the node) and its wiring (``check_graph``: each node's
input and output counts for its operator, every value defined before it is used, the graph's
one output produced; ``ValueError`` naming the node), then compiles the graph into a list of numpy
calls with the weights bound: ``Gemm`` keeps its weight matrix transposed once, so each call is
one ``matmul`` and one ``add``. ``run(x)`` feeds the graph's one input and returns its first
output. It needs numpy only, not the ``onnx`` package or onnxruntime.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from smartcar_gym.runtime.onnx_file import Model, Node

__all__ = ["ARITY", "OPERATORS", "NumpyGraph", "UnknownOperatorError", "check_graph"]

Op = Callable[..., np.ndarray]
#: a node's numpy call and the names of the values it takes at run time
Compiled = tuple[Op, list[str]]


class UnknownOperatorError(ValueError):
    """A graph with an operator the numpy evaluator does not run."""


#: OpenBLAS runs a matrix product of m x k by k x n on one thread while m * n * k is under
#: 65,536 x 4 (its SMP threshold), on several above: on a busy 2-core machine the threads took
#: 20-40 ms for 4,096 observations through a 64 or 128 wide layer, instead of 1-3 ms in blocks
SINGLE_THREAD_MNK = 65536 * 4


def _matmul(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``x @ w``, in blocks of rows small enough for one thread each."""
    rows = max(1, (SINGLE_THREAD_MNK - 1) // (w.shape[0] * w.shape[1]))
    n = x.shape[0] if x.ndim == 2 else 0
    if n <= rows:
        return x @ w
    out = np.empty((n, w.shape[1]), dtype=np.result_type(x, w))
    for start in range(0, n, rows):
        np.matmul(x[start:start + rows], w, out=out[start:start + rows])
    return out


def _gemm(node: Node, consts: dict[str, np.ndarray]) -> Compiled:
    """Y = alpha * A' @ B' + beta * C; with B and C initializers, ``x @ W' + b`` bound."""
    a = node.attributes
    alpha, beta = float(a.get("alpha", 1.0)), float(a.get("beta", 1.0))
    trans_a, trans_b = int(a.get("transA", 0)), int(a.get("transB", 0))
    x, weight = node.inputs[0], consts.get(node.inputs[1])
    c = node.inputs[2] if len(node.inputs) > 2 else ""
    if weight is not None and alpha == 1.0 and not trans_a and (not c or c in consts):
        w = np.ascontiguousarray(weight.T if trans_b else weight)
        if not c:
            return (lambda v: _matmul(v, w)), [x]
        b = (beta * consts[c]).astype(w.dtype)
        return (lambda v: np.add(_matmul(v, w), b)), [x]

    def gemm(v: np.ndarray, y: np.ndarray, bias: np.ndarray | None = None) -> np.ndarray:
        out = alpha * ((v.T if trans_a else v) @ (y.T if trans_b else y))
        return out if bias is None else out + beta * bias
    return gemm, list(node.inputs)


def _clip(node: Node, consts: dict[str, np.ndarray]) -> Compiled:
    """Clip with its bounds as inputs (opset >= 11) or attributes (older); "" is no bound."""
    bounds = list(node.inputs[1:3])
    if all(not name or name in consts for name in bounds):
        lo = consts[bounds[0]] if bounds and bounds[0] else node.attributes.get("min")
        hi = consts[bounds[1]] if len(bounds) > 1 and bounds[1] else node.attributes.get("max")
        return (lambda v: np.clip(v, lo, hi)), [node.inputs[0]]
    return (lambda v, lo=None, hi=None: np.clip(v, lo, hi)), list(node.inputs)


def _plain(function: Callable[..., np.ndarray]) -> Callable[[Node, dict], Compiled]:
    """An operator whose inputs are the function's arguments, in order."""
    return lambda node, consts: (function, list(node.inputs))


def _flatten(node: Node, consts: dict[str, np.ndarray]) -> Compiled:
    axis = int(node.attributes.get("axis", 1))
    return (lambda v: v.reshape(int(np.prod(v.shape[:axis])), -1)), [node.inputs[0]]


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, np.zeros((), dtype=x.dtype))


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return (1.0 / (1.0 + np.exp(-x))).astype(x.dtype)


#: operator -> compiler of its numpy call (given the node and the graph's constants)
OPERATORS: dict[str, Callable[[Node, dict[str, np.ndarray]], Compiled]] = {
    "Gemm": _gemm,
    "MatMul": _plain(np.matmul),
    "Add": _plain(np.add),
    "Sub": _plain(np.subtract),
    "Mul": _plain(np.multiply),
    "Div": _plain(np.divide),
    "Max": _plain(np.maximum),
    "Min": _plain(np.minimum),
    "Clip": _clip,
    "Tanh": _plain(np.tanh),
    "Relu": _plain(_relu),
    "Sigmoid": _plain(_sigmoid),
    "Neg": _plain(np.negative),
    "Identity": _plain(lambda x: x),
    "Flatten": _flatten,
}


#: operator -> (fewest inputs, most inputs, inputs that may be "" (left out)); one output each
ARITY: dict[str, tuple[int, int, tuple[int, ...]]] = {
    "Gemm": (2, 3, (2,)), "Clip": (1, 3, (1, 2)),
    **{op: (2, 2, ()) for op in ("MatMul", "Add", "Sub", "Mul", "Div", "Max", "Min")},
    **{op: (1, 1, ()) for op in ("Tanh", "Relu", "Sigmoid", "Neg", "Identity", "Flatten")},
}


def _label(node: Node, index: int) -> str:
    return f"node {node.name or index!r} ({node.op_type})"


def check_graph(model: Model) -> tuple[str, str]:
    """The names of ``model``'s one fed input and one output, after checking how its nodes
    are wired: each node has the inputs and one output its operator takes (``ARITY``; counts
    of other operators are not checked), uses only values defined before it (the input, an
    initializer or an earlier node's output) and defines each value once, and the output is
    produced. ``ValueError`` with one line naming the node and its operator otherwise."""
    graph = model.graph
    consts = graph.initializers
    feeds = [v.name for v in graph.inputs if v.name not in consts]
    if len(feeds) != 1 or len(graph.outputs) != 1:
        raise ValueError(f"the graph has {len(feeds)} inputs and {len(graph.outputs)} "
                         "outputs; a policy graph has one of each (observations in, "
                         "actions out)")
    defined = {*consts, feeds[0]}
    for index, node in enumerate(graph.nodes):
        label = _label(node, index)
        if node.op_type in ARITY:
            low, high, optional = ARITY[node.op_type]
            if not low <= len(node.inputs) <= high or len(node.outputs) != 1:
                takes = f"{low}" if low == high else f"{low} to {high}"
                raise ValueError(f"{label} has {len(node.inputs)} inputs and "
                                 f"{len(node.outputs)} outputs; {node.op_type} takes {takes} "
                                 "inputs and gives one output")
            left_out = [i for i, name in enumerate(node.inputs) if not name and i not in optional]
            if left_out:
                raise ValueError(f"{label} leaves out its input {left_out[0]}, which "
                                 f"{node.op_type} needs")
        elif not node.outputs:
            raise ValueError(f"{label} has no output")
        undefined = [name for name in node.inputs if name and name not in defined]
        if undefined:
            raise ValueError(f"{label} takes {undefined[0]!r}, which no earlier node, input "
                             "or initializer defines")
        again = [name for name in node.outputs if not name or name in defined]
        if again:
            raise ValueError(f"{label} defines {again[0]!r}, which is empty or defined "
                             "already (each value is defined once)")
        defined.update(node.outputs)
    output = graph.outputs[0].name
    if output not in defined:
        raise ValueError(f"the graph's output {output!r} is produced by no node")
    return feeds[0], output


class NumpyGraph:
    """``model``'s graph as numpy calls (see the module docstring)."""

    def __init__(self, model: Model) -> None:
        graph = model.graph
        unknown = [node for node in graph.nodes
                   if node.op_type not in OPERATORS or node.domain not in ("", "ai.onnx")]
        if unknown:
            node = unknown[0]
            op = node.op_type if not node.domain else f"{node.domain}.{node.op_type}"
            name = node.name or (node.outputs or [graph.nodes.index(node)])[0]
            raise UnknownOperatorError(
                f"operator {op} (node {name!r}) is not one the numpy "
                f"evaluator runs ({', '.join(OPERATORS)}); install onnxruntime "
                "(pip install \"smartcar-gym[onnx]\") to run this graph")
        self.input_name, self.output_name = check_graph(model)
        consts = dict(graph.initializers)
        self.constants = consts
        self.steps: list[tuple[Op, tuple[str, ...], str]] = []
        for index, node in enumerate(graph.nodes):
            try:
                call, inputs = OPERATORS[node.op_type](node, consts)
            except (TypeError, ValueError, KeyError, IndexError) as err:
                raise ValueError(f"{_label(node, index)}: its attributes cannot be read "
                                 f"({type(err).__name__}: {err})") from None
            self.steps.append((call, tuple(inputs), node.outputs[0]))

    def run(self, x: np.ndarray) -> np.ndarray:
        """The graph's output for the input ``x``."""
        values: dict[str, Any] = {**self.constants, "": None, self.input_name: x}
        for call, inputs, output in self.steps:
            values[output] = call(*[values[name] for name in inputs])
        return values[self.output_name]

