"""Re-encode a GGUF language model's quantized tensors as Q8_0 (numpy + gguf-py, no torch).

The registry packages ship SmolLM2-135M as Q4_1 and Gemma 3 270M as Q4_K_M. llama.cpp's
fast CPU matrix kernels for batches (llamafile sgemm: prompt evaluation and the draft
verification of aeris-llm) cover Q8_0 but not Q4_1 or the K-quants, so a batch runs
markedly slower on those files (measured on a 2-core x86-64 VM: a SmolLM2 decision
~840 ms as Q4_1, ~555 ms as Q8_0). Q8_0 holds every dequantized Q4_1/Q4_K value to within
8-bit rounding: the weights are the registry's, re-encoded, nothing is learned or added.

Usage: requantize_gguf.py SRC.gguf DST.gguf
"""

import sys

import numpy as np
from gguf import GGMLQuantizationType as T
from gguf import GGUFReader, GGUFValueType, GGUFWriter, quants

# kept as they are: already Q8_0, or float tensors (norms, biases)
KEEP = {T.Q8_0, T.F32, T.F16, T.BF16}


def field_value(field):
    kind = field.types[0]
    if kind == GGUFValueType.ARRAY:
        sub = field.types[1]
        if sub == GGUFValueType.STRING:
            return [bytes(field.parts[i]).decode("utf-8") for i in field.data], sub
        return [field.parts[i].tolist()[0] for i in field.data], sub
    if kind == GGUFValueType.STRING:
        return bytes(field.parts[field.data[0]]).decode("utf-8"), None
    return field.parts[field.data[0]].tolist()[0], None


def requantize(src, dst):
    reader = GGUFReader(src)
    arch_field = reader.fields["general.architecture"]
    arch = bytes(arch_field.parts[arch_field.data[0]]).decode("utf-8")
    writer = GGUFWriter(dst, arch)
    for name, field in reader.fields.items():
        if name.startswith("GGUF.") or name == "general.architecture":
            continue
        value, sub = field_value(field)
        writer.add_key_value(name, value, field.types[0], sub_type=sub)
    converted = 0
    for t in reader.tensors:
        kind = T(t.tensor_type)
        if kind in KEEP:
            writer.add_tensor(t.name, np.asarray(t.data), raw_dtype=kind)
            continue
        shape = [int(x) for x in reversed(t.shape.tolist())]
        values = quants.dequantize(t.data, kind).reshape(shape).astype(np.float32)
        writer.add_tensor(t.name, quants.quantize(values, T.Q8_0), raw_dtype=T.Q8_0)
        converted += 1
    writer.write_header_to_file()
    writer.write_kv_data_to_file()
    writer.write_tensors_to_file()
    writer.close()
    return converted


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    n = requantize(sys.argv[1], sys.argv[2])
    print(f"{sys.argv[2]}: {n} tensors re-encoded as Q8_0", file=sys.stderr)
