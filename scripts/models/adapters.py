#!/usr/bin/env python3
"""Install the committed LoRA adapters into the model cache (called by provision-models.sh).

Usage: adapters.py REPO_ADAPTERS_DIR CACHE_DIR

REPO_ADAPTERS_DIR/SHA256SUMS locks each adapter (`SHA256  NAME/adapter.gguf`, the file
scripts/train-reasoner.sh wrote); each is checked against it and installed as
CACHE_DIR/adapters/NAME.gguf, and CACHE_DIR/MANIFEST.sha256 lists it, so the runtime checks
an adapter before loading it like every model. Runs on every provisioning (cheap: a file is
copied only when it differs), so a new adapter reaches a cache provisioned before it.
Standard library only.
"""
import os
import shutil
import sys

from provision import sha256  # scripts/models/provision.py: the cache's one file hash


def main(repo, cache):
    sums = os.path.join(repo, "SHA256SUMS")
    if not os.path.isfile(sums):
        return 0
    manifest_path = os.path.join(cache, "MANIFEST.sha256")
    with open(manifest_path) as f:
        manifest = dict(
            (line.split("  ", 1)[1].rstrip("\n"), line.split("  ", 1)[0]) for line in f if "  " in line
        )
    changed = False
    with open(sums) as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            try:
                digest, rel = line.split(None, 1)
            except ValueError:
                raise SystemExit(f"provision: {sums}, line {n}: not `SHA256  NAME/adapter.gguf`")
            name = rel.split("/", 1)[0]
            if rel != f"{name}/adapter.gguf" or not name or name.startswith("."):
                raise SystemExit(f"provision: {sums}, line {n}: `{rel}` is not NAME/adapter.gguf")
            source = os.path.join(repo, rel)
            if sha256(source) != digest:
                raise SystemExit(f"provision: {source} does not match its sha256 in {sums}")
            cached = f"adapters/{name}.gguf"
            dest = os.path.join(cache, cached)
            if manifest.get(cached) != digest or not os.path.isfile(dest) or sha256(dest) != digest:
                os.makedirs(os.path.dirname(dest), exist_ok=True)
                shutil.copyfile(source, dest + ".part")
                os.replace(dest + ".part", dest)
                manifest[cached] = digest
                changed = True
                print(f"provision: adapter {name} -> {cached}", file=sys.stderr)
    if changed:
        with open(manifest_path + ".part", "w") as out:
            out.write("".join(f"{manifest[k]}  {k}\n" for k in sorted(manifest)))
        os.replace(manifest_path + ".part", manifest_path)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
