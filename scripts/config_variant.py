#!/usr/bin/python3
"""A config file that is BASE with some keys set: what a recipe variant trains with.

    scripts/config_variant.py BASE.toml OUT.toml train.epochs=24 model.speed_input=true ...

Each override is TABLE.KEY=VALUE (a dotted path for nested tables, e.g. collect.noise.enabled);
VALUE is read as TOML (24, 2e-4, true, "resnet34"; a bare word is a string). The merged config
is written atomically, tables in the base file's order; comments are not carried over.
"""
import os
import sys
import tomllib


def parse_value(text):
    try:
        return tomllib.loads("v = " + text)["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare word: a string


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise SystemExit(f"error: cannot write {v!r} as a TOML value")


def write_table(lines, path, table):
    plain = {k: v for k, v in table.items() if not isinstance(v, dict)}
    if path and plain:
        lines.append(f"[{'.'.join(path)}]")
    for k, v in plain.items():
        lines.append(f"{k} = {toml_value(v)}")
    if plain:
        lines.append("")
    for k, v in table.items():
        if isinstance(v, dict):
            write_table(lines, path + [k], v)


def main(argv):
    if len(argv) < 3:
        raise SystemExit(__doc__.strip().splitlines()[2].strip())
    base, out, overrides = argv[1], argv[2], argv[3:]
    try:
        with open(base, "rb") as f:
            config = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise SystemExit(f"error: {base}: {e}")
    for item in overrides:
        key, sep, value = item.partition("=")
        parts = key.split(".")
        if not sep or len(parts) < 2 or not all(parts):
            raise SystemExit(f"error: override '{item}' is not TABLE.KEY=VALUE")
        table = config
        for p in parts[:-1]:
            table = table.setdefault(p, {})
            if not isinstance(table, dict):
                raise SystemExit(f"error: override '{item}': {p} is not a table")
        table[parts[-1]] = parse_value(value)
    lines = []
    write_table(lines, [], config)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines))
    os.replace(tmp, out)


if __name__ == "__main__":
    main(sys.argv)
