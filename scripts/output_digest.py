"""One line per output file of a folder: a digest of its bytes and its path (scripts/same_bytes.sh).

JSON and JSON-lines files are digested without the keys that hold times, throughputs, devices
or paths (they differ between any two runs), with the folder itself replaced by ROOT; with
IGNORE_SETTINGS=1 also without the "settings" section of run records (for a change that moves
a key between tables). optimizer.pt is listed but not digested: libtorch writes Adam's state in
an order that varies between runs (the models, and a resumed run's bytes, do not).
"""
import hashlib
import json
import os
import re
import sys

VARYING = re.compile(r"(seconds|per_s|time|device|source|data_dir|out_dir|^dir$|^out$|init"
                     r"|vae_from|copied_from|^file$|checkpoint|path)", re.I)


IGNORE_SETTINGS = os.environ.get("IGNORE_SETTINGS") == "1"


def clean(x, root):
    if isinstance(x, dict):
        return {k: clean(v, root) for k, v in x.items()
                if not VARYING.search(k) and not (IGNORE_SETTINGS and k == "settings")}
    if isinstance(x, list):
        return [clean(v, root) for v in x]
    if isinstance(x, str):
        return x.replace(root, "ROOT")
    return x


def main(root):
    for folder, _, files in sorted(os.walk(root)):
        for name in sorted(files):
            # causaldrive.lock names its holder and time: the run folder's lock, not an output.
            if name in ("log", "cfg.toml", "causaldrive.lock") or name.endswith(".digest"):
                continue
            path = os.path.join(folder, name)
            if name == "optimizer.pt":
                print("(varies)        ", os.path.relpath(path, root))
                continue
            data = open(path, "rb").read()
            if name.endswith((".json", ".jsonl")):
                text = data.decode()
                objs = ([json.loads(l) for l in text.splitlines() if l.strip()]
                        if name.endswith(".jsonl") else json.loads(text))
                data = json.dumps(clean(objs, root), sort_keys=True).encode()
            print(hashlib.sha256(data).hexdigest()[:16], os.path.relpath(path, root))


if __name__ == "__main__":
    main(sys.argv[1])
