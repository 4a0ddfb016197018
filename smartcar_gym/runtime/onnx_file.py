"""Reading an ONNX file without the ``onnx`` package: the protobuf fields a policy graph uses.

An ONNX model is a protobuf ``ModelProto``. ``read_model(data)`` decodes what the numpy
evaluator needs of it, with nothing but the standard library and numpy: the graph's nodes
(operator, inputs, outputs, attributes), its initializers (the weights, as numpy arrays), its
inputs and outputs with their shapes, the opset versions and the metadata properties. Fields it
does not know are skipped, as protobuf readers do. A file that is not such a message raises
``OnnxFormatError`` naming what was wrong.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Graph", "Model", "Node", "OnnxFormatError", "ValueInfo", "read_model"]

#: ONNX TensorProto.DataType -> numpy dtype (the numeric types a policy graph holds)
DTYPES = {1: np.float32, 2: np.uint8, 3: np.int8, 5: np.int16, 6: np.int32, 7: np.int64,
          9: np.bool_, 10: np.float16, 11: np.float64}
_WIRE_VARINT, _WIRE_64, _WIRE_BYTES, _WIRE_32 = 0, 1, 2, 5


class OnnxFormatError(ValueError):
    """Bytes that are not an ONNX model (the message says what was wrong)."""


@dataclass
class Node:
    """One operator of the graph."""

    op_type: str
    inputs: list[str]
    outputs: list[str]
    name: str = ""
    domain: str = ""
    attributes: dict[str, Any] = field(default_factory=dict)


@dataclass
class ValueInfo:
    """A graph input or output: its name, element type and shape (None: a symbolic dim)."""

    name: str
    elem_type: int = 0
    shape: tuple[int | None, ...] | None = None


@dataclass
class Graph:
    """The graph: nodes in file order, initializers by name, inputs and outputs."""

    nodes: list[Node] = field(default_factory=list)
    initializers: dict[str, np.ndarray] = field(default_factory=dict)
    inputs: list[ValueInfo] = field(default_factory=list)
    outputs: list[ValueInfo] = field(default_factory=list)


@dataclass
class Model:
    """An ONNX model: its graph, opsets (domain -> version) and metadata properties."""

    graph: Graph
    ir_version: int = 0
    opsets: dict[str, int] = field(default_factory=dict)
    metadata: dict[str, str] = field(default_factory=dict)
    producer: str = ""


def _fields(data: bytes) -> list[tuple[int, int, Any]]:
    """The (field number, wire type, value) of a message: ints for varints and fixed
    widths (as raw bytes for the fixed ones), bytes for length-delimited fields."""
    out: list[tuple[int, int, Any]] = []
    pos, end = 0, len(data)
    while pos < end:
        key, pos = _varint(data, pos)
        number, wire = key >> 3, key & 7
        if number == 0:
            raise OnnxFormatError("a protobuf field numbered 0")
        if wire == _WIRE_VARINT:
            value, pos = _varint(data, pos)
        elif wire == _WIRE_64:
            value, pos = data[pos:pos + 8], pos + 8
        elif wire == _WIRE_BYTES:
            size, pos = _varint(data, pos)
            value, pos = data[pos:pos + size], pos + size
        elif wire == _WIRE_32:
            value, pos = data[pos:pos + 4], pos + 4
        else:
            raise OnnxFormatError(f"protobuf wire type {wire} (field {number})")
        if pos > end:
            raise OnnxFormatError(f"field {number} runs past the end of its message")
        out.append((number, wire, value))
    return out


def _varint(data: bytes, pos: int) -> tuple[int, int]:
    result = shift = 0
    while True:
        if pos >= len(data):
            raise OnnxFormatError("a protobuf varint runs past the end")
        byte = data[pos]
        pos += 1
        result |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return result, pos
        shift += 7
        if shift > 63:
            raise OnnxFormatError("a protobuf varint longer than 10 bytes")


def _signed(value: int) -> int:
    """A varint read as int64 (two's complement)."""
    return value - (1 << 64) if value >= 1 << 63 else value


def _text(value: Any) -> str:
    if not isinstance(value, bytes):
        raise OnnxFormatError("a string field that is not length-delimited")
    try:
        return value.decode("utf-8")
    except UnicodeDecodeError as err:
        raise OnnxFormatError(f"a string field that is not UTF-8 ({err})") from None


def _ints(wire: int, value: Any) -> list[int]:
    """A repeated int64 field's values from one entry: packed or one varint."""
    if wire == _WIRE_VARINT:
        return [_signed(value)]
    values, pos = [], 0
    while pos < len(value):
        item, pos = _varint(value, pos)
        values.append(_signed(item))
    return values


def _floats(wire: int, value: Any) -> list[float]:
    """A repeated float field's values from one entry: packed or one fixed32."""
    return list(struct.unpack(f"<{len(value) // 4}f", value)) if wire in (_WIRE_BYTES,
                                                                         _WIRE_32) else []


def _tensor(data: bytes) -> tuple[str, np.ndarray]:
    dims: list[int] = []
    dtype_code, name, raw = 0, "", None
    floats: list[float] = []
    int64s: list[int] = []
    int32s: list[int] = []
    doubles: list[float] = []
    for number, wire, value in _fields(data):
        if number == 1:
            dims += _ints(wire, value)
        elif number == 2:
            dtype_code = value
        elif number == 4:
            floats += _floats(wire, value)
        elif number == 5:
            int32s += _ints(wire, value)
        elif number == 7:
            int64s += _ints(wire, value)
        elif number == 8:
            name = _text(value)
        elif number == 9:
            raw = value
        elif number == 10:
            doubles += (list(struct.unpack(f"<{len(value) // 8}d", value))
                        if wire == _WIRE_BYTES else list(struct.unpack("<d", value)))
        elif number == 13:
            raise OnnxFormatError(f"tensor {name!r} keeps its data in an external file")
    if dtype_code not in DTYPES:
        raise OnnxFormatError(f"tensor {name!r} has ONNX data type {dtype_code}, not a numeric "
                              "one the evaluator reads")
    dtype = np.dtype(DTYPES[dtype_code]).newbyteorder("<")
    if raw is not None:
        array = np.frombuffer(raw, dtype=dtype).astype(dtype.newbyteorder("="))
    elif dtype_code in (1, 10):
        array = np.array(floats, dtype=dtype.newbyteorder("="))
    elif dtype_code == 11:
        array = np.array(doubles, dtype=np.float64)
    else:
        array = np.array(int64s if dtype_code == 7 else int32s, dtype=dtype.newbyteorder("="))
    size = int(np.prod(dims)) if dims else 1
    if array.size != size:
        raise OnnxFormatError(f"tensor {name!r} holds {array.size} values for its shape "
                              f"{tuple(dims)}")
    return name, array.reshape(dims)


def _attribute(data: bytes) -> tuple[str, Any]:
    name, kind, values = "", 0, {}
    ints: list[int] = []
    floats: list[float] = []
    for number, wire, value in _fields(data):
        if number == 1:
            name = _text(value)
        elif number == 2:
            values["f"] = struct.unpack("<f", value)[0]
        elif number == 3:
            values["i"] = _signed(value)
        elif number == 4:
            values["s"] = value
        elif number == 5:
            values["t"] = _tensor(value)[1]
        elif number == 7:
            floats += _floats(wire, value)
        elif number == 8:
            ints += _ints(wire, value)
        elif number == 20:
            kind = value
    by_kind = {1: "f", 2: "i", 3: "s", 4: "t"}
    if kind in by_kind and by_kind[kind] in values:
        return name, values[by_kind[kind]]
    if kind == 6 or (floats and not ints):
        return name, floats
    if kind == 7 or ints:
        return name, ints
    return name, next(iter(values.values()), None)


#: NodeProto's string fields other than its inputs (1) and outputs (2)
_NODE_TEXT = {3: "name", 4: "op_type", 7: "domain"}


def _node(data: bytes) -> Node:
    node = Node("", [], [])
    for number, _wire, value in _fields(data):
        if number in (1, 2):
            (node.inputs if number == 1 else node.outputs).append(_text(value))
        elif number in _NODE_TEXT:
            setattr(node, _NODE_TEXT[number], _text(value))
        elif number == 5:
            key, attribute = _attribute(value)
            node.attributes[key] = attribute
    return node


def _value_info(data: bytes) -> ValueInfo:
    info = ValueInfo("")
    for number, _wire, value in _fields(data):
        if number == 1:
            info.name = _text(value)
        elif number == 2:  # TypeProto
            for t_number, _, tensor_type in _fields(value):
                if t_number == 1:  # TypeProto.Tensor
                    _tensor_type(tensor_type, info)
    return info


def _tensor_type(data: bytes, info: ValueInfo) -> None:
    for number, _wire, value in _fields(data):
        if number == 1:
            info.elem_type = value
        elif number == 2:  # TensorShapeProto
            dims: list[int | None] = []
            for d_number, _, dim in _fields(value):
                if d_number == 1:
                    size = [v for n, _, v in _fields(dim) if n == 1]
                    dims.append(_signed(size[0]) if size else None)
            info.shape = tuple(dims)


def _graph(data: bytes) -> Graph:
    graph = Graph()
    for number, _wire, value in _fields(data):
        if number == 1:
            graph.nodes.append(_node(value))
        elif number == 5:
            key, array = _tensor(value)
            graph.initializers[key] = array
        elif number in (11, 12):
            (graph.inputs if number == 11 else graph.outputs).append(_value_info(value))
    return graph


def read_model(data: bytes) -> Model:
    """The ``Model`` that ``data`` (an ONNX file's bytes) holds; ``OnnxFormatError`` if it
    is no ONNX model (not protobuf, or no graph)."""
    graph: Graph | None = None
    model = Model(Graph())
    try:
        fields = _fields(data)
        for number, _wire, value in fields:
            if number == 1:
                model.ir_version = value
            elif number == 2:
                model.producer = _text(value)
            elif number == 7:
                graph = _graph(value)
            elif number == 8:
                entry = {n: v for n, _, v in _fields(value)}
                model.opsets[_text(entry.get(1, b""))] = int(entry.get(2, 0))
            elif number == 14:
                entry = {n: v for n, _, v in _fields(value)}
                model.metadata[_text(entry.get(1, b""))] = _text(entry.get(2, b""))
    except (struct.error, TypeError, ValueError) as err:
        if isinstance(err, OnnxFormatError):
            raise
        raise OnnxFormatError(f"malformed protobuf ({err})") from None
    if graph is None or not graph.nodes or model.ir_version == 0:
        raise OnnxFormatError("no ONNX graph in it (an ONNX model has an ir_version and a "
                              "graph of nodes)")
    model.graph = graph
    return model
