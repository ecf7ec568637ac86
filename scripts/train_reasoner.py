#!/usr/bin/env python3
"""LoRA-tune a provisioned GGUF base on `aeris distill` pairs and export a llama.cpp adapter.

    scripts/train-reasoner.sh --base smollm2 --pairs runs/distill-train-aeris-planner/pairs.jsonl \
        --out models/adapters/smollm2-aligned

What it does, in order:
1. loads the base from the provisioned model cache ($AERIS_MODELS, else ~/.cache/aeris/models:
   the very GGUF file the runtime decodes with; transformers dequantizes it);
2. reads the pairs (`system`, `user`, `target`), drops exact repeats (a hovering teacher
   writes the same pair for many heartbeats), holds out whole scenes for validation
   (--val-scenes), and renders each prompt with the base's own chat template;
3. trains LoRA adapters (peft) on every linear layer of the attention and MLP, the loss on
   the decision's tokens only, bf16 autocast where the CPU has it; --time-steps N first
   times N steps and says how long the whole run would take (--time-only stops there);
4. writes the peft adapter, the llama.cpp LoRA GGUF (`adapter.gguf`, gguf-py: llama.cpp's
   converter script is not in the sources the Rust crate ships), the next-token logits of a
   fixed prompt with the adapter (`check.json`, which `llm/tests/adapter.rs` compares with
   llama.cpp's), and `train.json`: the command, seed, data, losses and times.

The decision's target is what the grammar writes (`DecisionView::to_json`); the runtime
decodes it under the same grammar, so the model learns the choice, never the format alone.
"""

import argparse
import hashlib
import json
import math
import os
import random
import sys
import time
from pathlib import Path

BASES = {
    # variant: (cache-relative GGUF, tokens that end a turn)
    "smollm2": "llm/smollm2-135m-instruct-q8_0.gguf",
    "gemma3": "llm/gemma-3-270m-q4_k_m.gguf",
    "qwen-coder": "llm/qwen2.5-coder-0.5b-instruct-q4_k_m.gguf",
}

# HF module name -> llama.cpp tensor name (per block)
GGUF_NAMES = {
    "self_attn.q_proj": "attn_q",
    "self_attn.k_proj": "attn_k",
    "self_attn.v_proj": "attn_v",
    "self_attn.o_proj": "attn_output",
    "mlp.gate_proj": "ffn_gate",
    "mlp.up_proj": "ffn_up",
    "mlp.down_proj": "ffn_down",
}

CHECK_PROMPT_PAIRS = 3


def parse_args(argv):
    p = argparse.ArgumentParser(prog="train_reasoner.py", description=__doc__.split("\n")[0])
    p.add_argument("--base", choices=sorted(BASES), default="smollm2", help="the base model (default smollm2)")
    p.add_argument("--pairs", nargs="+", required=True, metavar="FILE", help="pairs.jsonl files of `aeris distill`")
    p.add_argument("--out", required=True, metavar="DIR", help="where the adapter and its figures go")
    p.add_argument("--models-dir", default=None, metavar="DIR", help="the model cache (default $AERIS_MODELS or ~/.cache/aeris/models)")
    p.add_argument("--epochs", type=float, default=2.0, help="passes over the training pairs (default 2)")
    p.add_argument("--batch", type=int, default=8, help="sequences per step (default 8)")
    p.add_argument("--lr", type=float, default=2e-4, help="learning rate (default 2e-4)")
    p.add_argument("--rank", type=int, default=8, help="LoRA rank (default 8)")
    p.add_argument("--alpha", type=float, default=16.0, help="LoRA alpha (default 16)")
    p.add_argument("--seed", type=int, default=37, help="data order and initialisation seed (default 37)")
    p.add_argument("--val-scenes", type=int, default=2, help="whole scenes held out for validation (default 2)")
    p.add_argument("--max-pairs", type=int, default=None, help="use at most this many training pairs")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: all CPUs)")
    p.add_argument("--time-steps", type=int, default=20, help="steps timed before the run (default 20; 0: none)")
    p.add_argument("--time-only", action="store_true", help="stop after timing the first steps")
    p.add_argument(
        "--keep-failed",
        action="store_true",
        help="also train on pairs of episodes the teacher flew and failed (default: dropped; a DAgger round's pairs are kept)",
    )
    p.add_argument(
        "--dagger-repeats",
        type=int,
        default=3,
        help="at most this many DAgger pairs for one episode, memory line and label (default 3)",
    )
    p.add_argument("--init", default=None, metavar="DIR", help="start from this run's peft adapter (DIR/peft) instead of a new one")
    p.add_argument(
        "--step-changes",
        type=int,
        default=1,
        metavar="K",
        help="train on each pair whose decision moves to another step K times (default 1): they "
        "are a few percent of the pairs, and a model that never sees them copies its last decision",
    )
    args = p.parse_args(argv)
    if args.batch < 1 or args.rank < 1 or args.epochs <= 0:
        p.error("--batch, --rank and --epochs must be positive")
    return args


def models_dir(args) -> Path:
    if args.models_dir:
        return Path(args.models_dir)
    env = os.environ.get("AERIS_MODELS")
    return Path(env) if env else Path.home() / ".cache" / "aeris" / "models"


def memory_line(pair):
    """The prompt's memory line (the last decision), or ""."""
    return next((l for l in pair["user"].split("\n") if l.startswith("Last: ")), "")


def load_pairs(files, keep_failed, dagger_repeats):
    """The distinct pairs of `files`; without `keep_failed` not those of episodes the teacher
    flew and failed (`success` false, written by `aeris distill`; a DAgger round's pairs,
    `dagger` true, are the teacher's labels of a student's states whatever the student did,
    and a pair without `success` is kept). Of a DAgger round's pairs at most
    `dagger_repeats` (as read, before duplicates are dropped) for one episode, memory line and
    label: a student stuck in one state asks the same question for minutes."""
    pairs, seen, repeats = [], set(), {}
    for f in files:
        with open(f, encoding="utf-8") as fh:
            for n, line in enumerate(fh, 1):
                try:
                    p = json.loads(line)
                    key = (p["system"], p["user"], p["target"])
                except (json.JSONDecodeError, KeyError, TypeError) as e:
                    sys.exit(f"train_reasoner: {f}, line {n}: not a training pair ({e})")
                if p.get("dagger"):
                    state = (p.get("episode_id", ""), memory_line(p), p["target"])
                    repeats[state] = repeats.get(state, 0) + 1
                    if repeats[state] > dagger_repeats:
                        continue
                if key in seen or (not keep_failed and p.get("success") is False and not p.get("dagger")):
                    continue
                seen.add(key)
                pairs.append(p)
    return pairs


def split_by_scene(pairs, val_scenes, seed):
    scenes = sorted({p.get("scene_id", "") for p in pairs})
    random.Random(seed).shuffle(scenes)
    held = set(scenes[:val_scenes]) if len(scenes) > val_scenes else set()
    train = [p for p in pairs if p.get("scene_id", "") not in held]
    val = [p for p in pairs if p.get("scene_id", "") in held]
    return train, val, sorted(held)


def render(tokenizer, pair):
    """Prompt ids (the chat template with the generation prompt, as llama.cpp applies the
    GGUF's template) and the target's ids."""
    messages = [{"role": "system", "content": pair["system"]}, {"role": "user", "content": pair["user"]}]
    text = tokenizer.apply_chat_template(messages, add_generation_prompt=True, tokenize=False)
    prompt = tokenizer(text, add_special_tokens=False)["input_ids"]
    target = tokenizer(pair["target"], add_special_tokens=False)["input_ids"]
    return text, prompt, target


def changes_step(pair):
    """Whether the pair's decision moves to another step than its memory line's."""
    line = memory_line(pair)
    if not line or line == "Last: none.":
        return False
    return int(line.split()[1]) != json.loads(pair["target"])["step"]


def batches(examples, batch, rng):
    """Batches of similar length (little padding): sort by length in chunks, shuffle the
    batches."""
    order = list(range(len(examples)))
    rng.shuffle(order)
    chunk = batch * 16
    out = []
    for i in range(0, len(order), chunk):
        part = sorted(order[i : i + chunk], key=lambda k: len(examples[k][0]) + len(examples[k][1]))
        out.extend(part[j : j + batch] for j in range(0, len(part), batch))
    rng.shuffle(out)
    return out


def collate(torch, examples, idx, pad_id):
    seqs = [examples[k][0] + examples[k][1] for k in idx]
    width = max(len(s) for s in seqs)
    ids = torch.full((len(idx), width), pad_id, dtype=torch.long)
    labels = torch.full((len(idx), width), -100, dtype=torch.long)
    mask = torch.zeros((len(idx), width), dtype=torch.long)
    for r, k in enumerate(idx):
        prompt, target = examples[k]
        n = len(prompt) + len(target)
        ids[r, :n] = torch.tensor(prompt + target)
        labels[r, len(prompt) : n] = torch.tensor(target)
        mask[r, :n] = 1
    return ids, labels, mask


def bf16_ok(torch):
    try:
        flags = open("/proc/cpuinfo").read()
    except OSError:
        flags = ""
    return "avx512_bf16" in flags or "amx_bf16" in flags or torch.cuda.is_available()


def mean_loss(torch, model, examples, batch, pad_id, device, autocast):
    if not examples:
        return None
    model.eval()
    total, count = 0.0, 0
    with torch.no_grad():
        for i in range(0, len(examples), batch):
            idx = list(range(i, min(i + batch, len(examples))))
            ids, labels, mask = (t.to(device) for t in collate(torch, examples, idx, pad_id))
            with autocast():
                out = model(input_ids=ids, attention_mask=mask, labels=labels)
            n = int((labels[:, 1:] != -100).sum())
            total += float(out.loss) * n
            count += n
    model.train()
    return total / max(count, 1)


def permute_rows(w, n_head, n_head_kv):
    """llama.cpp's row order of a llama q/k projection (convert_hf_to_gguf's permute)."""
    if n_head_kv is not None and n_head != n_head_kv:
        n_head = n_head_kv
    return w.reshape(n_head, 2, w.shape[0] // n_head // 2, *w.shape[1:]).swapaxes(1, 2).reshape(w.shape)


def export_gguf(model, config, arch, alpha, path):
    import gguf
    import numpy as np

    writer = gguf.GGUFWriter(str(path), arch)
    writer.add_string("general.type", "adapter")
    writer.add_string("adapter.type", "lora")
    writer.add_float32("adapter.lora.alpha", float(alpha))
    n_head = config.num_attention_heads
    n_kv = getattr(config, "num_key_value_heads", n_head)
    count = 0
    for name, module in model.named_modules():
        if not hasattr(module, "lora_A") or "default" not in getattr(module, "lora_A", {}):
            continue
        parts = name.split(".")
        layer = int(parts[parts.index("layers") + 1])
        suffix = ".".join(parts[parts.index("layers") + 2 :])
        base = GGUF_NAMES.get(suffix)
        if base is None:
            sys.exit(f"train_reasoner: no llama.cpp name for {name}")
        a = module.lora_A["default"].weight.detach().float().cpu().numpy()  # (r, in)
        b = module.lora_B["default"].weight.detach().float().cpu().numpy()  # (out, r)
        if arch == "llama" and base == "attn_q":
            b = permute_rows(b, n_head, n_head)
        elif arch == "llama" and base == "attn_k":
            b = permute_rows(b, n_head, n_kv)
        tensor = f"blk.{layer}.{base}.weight"
        writer.add_tensor(f"{tensor}.lora_a", np.ascontiguousarray(a, dtype=np.float32))
        writer.add_tensor(f"{tensor}.lora_b", np.ascontiguousarray(b, dtype=np.float32))
        count += 1
    writer.write_header_to_file()
    writer.write_kv_data_to_file()
    writer.write_tensors_to_file()
    writer.close()
    return count


def gguf_arch(path):
    import gguf

    reader = gguf.GGUFReader(str(path))
    field = reader.fields["general.architecture"]
    return bytes(field.parts[field.data[0]]).decode()


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def main(argv):
    args = parse_args(argv)
    import torch
    from peft import LoraConfig, get_peft_model
    from transformers import AutoModelForCausalLM, AutoTokenizer

    random.seed(args.seed)
    torch.manual_seed(args.seed)
    if args.threads:
        torch.set_num_threads(args.threads)
    started = time.monotonic()
    cache = models_dir(args)
    file = BASES[args.base]
    gguf_path = cache / file
    if not gguf_path.is_file():
        sys.exit(f"train_reasoner: {gguf_path}: not provisioned (scripts/setup.sh fetches the models)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"train_reasoner: base {args.base} from {gguf_path}", file=sys.stderr)
    tokenizer = AutoTokenizer.from_pretrained(str(gguf_path.parent), gguf_file=gguf_path.name)
    model = AutoModelForCausalLM.from_pretrained(str(gguf_path.parent), gguf_file=gguf_path.name, torch_dtype=torch.float32)
    pad_id = tokenizer.pad_token_id if tokenizer.pad_token_id is not None else tokenizer.eos_token_id
    pairs = load_pairs(args.pairs, args.keep_failed, args.dagger_repeats)
    train_pairs, val_pairs, held = split_by_scene(pairs, args.val_scenes, args.seed)
    changes = [p for p in train_pairs if changes_step(p)]
    if args.max_pairs is not None:
        random.Random(args.seed).shuffle(train_pairs)
        train_pairs = train_pairs[: args.max_pairs]
    if not train_pairs:
        sys.exit("train_reasoner: no training pairs left (more scenes than --val-scenes are needed)")
    if args.step_changes > 1:
        # every step change of the training scenes (also those --max-pairs left out), K times
        train_pairs = [p for p in train_pairs if not changes_step(p)] + changes * args.step_changes
        print(f"train_reasoner: {len(changes)} pairs change step, each {args.step_changes} times", file=sys.stderr)
    train = [render(tokenizer, p)[1:] for p in train_pairs]
    val = [render(tokenizer, p)[1:] for p in val_pairs]
    tokens = sum(len(a) + len(b) for a, b in train)
    print(
        f"train_reasoner: {len(train)} training pairs ({tokens} tokens), {len(val)} validation pairs "
        f"(scenes {', '.join(held) or 'none'})",
        file=sys.stderr,
    )
    lora = LoraConfig(
        r=args.rank,
        lora_alpha=args.alpha,
        lora_dropout=0.0,
        target_modules=[k.split(".")[1] for k in GGUF_NAMES],
        bias="none",
        task_type="CAUSAL_LM",
    )
    if args.init:
        from peft import PeftModel

        model = PeftModel.from_pretrained(model, str(Path(args.init) / "peft"), is_trainable=True)
    else:
        model = get_peft_model(model, lora)
    trainable = sum(p.numel() for p in model.parameters() if p.requires_grad)
    device = "cuda" if torch.cuda.is_available() else "cpu"
    model.to(device)
    use_bf16 = bf16_ok(torch)

    def autocast():
        return torch.autocast(device_type=device, dtype=torch.bfloat16, enabled=use_bf16)

    optimizer = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=args.lr, weight_decay=0.0)
    rng = random.Random(args.seed)
    steps_per_epoch = math.ceil(len(train) / args.batch)
    total_steps = max(1, math.ceil(args.epochs * steps_per_epoch))
    schedule = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda s: min(1.0, (s + 1) / 10) * max(0.0, 1 - s / total_steps)
    )
    val_before = mean_loss(torch, model, val, args.batch, pad_id, device, autocast)
    print(f"train_reasoner: {trainable} trainable parameters, {total_steps} steps, bf16 {use_bf16}, "
          f"validation loss before {val_before}", file=sys.stderr)
    model.train()
    step, losses, timed = 0, [], None
    t0 = time.monotonic()
    while step < total_steps:
        for idx in batches(train, args.batch, rng):
            if step >= total_steps:
                break
            ids, labels, mask = (t.to(device) for t in collate(torch, train, idx, pad_id))
            with autocast():
                loss = model(input_ids=ids, attention_mask=mask, labels=labels).loss
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            optimizer.step()
            schedule.step()
            optimizer.zero_grad(set_to_none=True)
            losses.append(float(loss.detach()))
            step += 1
            if args.time_steps and step == args.time_steps:
                timed = (time.monotonic() - t0) / step
                print(
                    f"train_reasoner: {step} steps in {time.monotonic() - t0:.1f} s: {timed:.2f} s a step, "
                    f"the run of {total_steps} steps about {timed * total_steps / 60:.1f} min",
                    file=sys.stderr,
                )
                if args.time_only:
                    return 0
            if step % 25 == 0 or step == total_steps:
                recent = losses[-25:]
                print(f"train_reasoner: step {step}/{total_steps} loss {sum(recent) / len(recent):.4f} "
                      f"({time.monotonic() - t0:.0f} s)", file=sys.stderr)
    train_s = time.monotonic() - t0
    val_after = mean_loss(torch, model, val, args.batch, pad_id, device, autocast)
    print(f"train_reasoner: validation loss {val_before} -> {val_after}", file=sys.stderr)
    model.save_pretrained(str(out / "peft"))
    arch = gguf_arch(gguf_path)
    adapter = out / "adapter.gguf"
    n = export_gguf(model, model.base_model.model.config, arch, args.alpha, adapter)
    # the reference llama.cpp is checked against: next-token logits after a fixed prompt
    check_pairs = (val_pairs or train_pairs)[:CHECK_PROMPT_PAIRS]
    checks = []
    model.eval()
    with torch.no_grad():
        for p in check_pairs:
            text, prompt, target = render(tokenizer, p)
            ids = torch.tensor([prompt + target[:4]], device=device)
            logits = model(input_ids=ids).logits[0, -1].float()
            top = torch.topk(logits, 8)
            checks.append({
                "system": p["system"],
                "user": p["user"],
                "prompt_text": text,
                "tokens": prompt + target[:4],
                "top_tokens": top.indices.tolist(),
                "top_logits": [round(v, 4) for v in top.values.tolist()],
            })
    (out / "check.json").write_text(json.dumps({"base": file, "checks": checks}, indent=1) + "\n")
    record = {
        "command": "scripts/train-reasoner.sh " + " ".join(argv),
        "base": file,
        "base_sha256": sha256(gguf_path),
        "arch": arch,
        "pairs_files": [{"path": str(f), "sha256": sha256(f)} for f in args.pairs],
        "train_pairs": len(train),
        "val_pairs": len(val),
        "val_scenes": held,
        "seed": args.seed,
        "init": args.init,
        "step_changes": args.step_changes,
        "keep_failed": args.keep_failed,
        "dagger_repeats": args.dagger_repeats,
        "rank": args.rank,
        "alpha": args.alpha,
        "lr": args.lr,
        "batch": args.batch,
        "epochs": args.epochs,
        "steps": step,
        "trainable_parameters": trainable,
        "bf16": use_bf16,
        "threads": torch.get_num_threads(),
        "cpu": cpu_name(),
        "seconds_a_step": train_s / max(step, 1),
        "train_s": train_s,
        "total_s": time.monotonic() - started,
        "loss_first_25": sum(losses[:25]) / max(1, len(losses[:25])),
        "loss_last_25": sum(losses[-25:]) / max(1, len(losses[-25:])),
        "val_loss_before": val_before,
        "val_loss_after": val_after,
        "adapter": "adapter.gguf",
        "adapter_sha256": sha256(adapter),
        "adapter_tensors": n,
        "versions": {"torch": torch.__version__, **versions()},
    }
    (out / "train.json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"train_reasoner: {adapter} ({n} LoRA pairs, sha256 {record['adapter_sha256']}); "
          f"{step} steps in {train_s / 60:.1f} min", file=sys.stderr)
    return 0


def cpu_name():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def versions():
    """The installed versions of the training packages (gguf has no `__version__`: the
    distribution's metadata says it)."""
    from importlib import metadata

    out = {}
    for name in ("transformers", "peft", "gguf"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
