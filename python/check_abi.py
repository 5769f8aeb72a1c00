#!/usr/bin/env python3
"""Checks the generated ctypes declarations against the C compiler.

usage: check_abi.py ABI_PY LAYOUT_EXE [LIBRARY]

ABI_PY is the _abi.py that gen_abi.py wrote, LAYOUT_EXE the program built from
the C file it wrote with it (sizeof, alignment, every field's offset and size,
every enumerator, every constant as the compiler sees them). Every line must
agree with ctypes; with LIBRARY, every declared function must also be
exported by it. Prints one line per disagreement and ends with
"N passed, N failed". Standard library only (no numpy).
"""
import ctypes
import importlib.util
import subprocess
import sys


def load_abi(path):
    spec = importlib.util.spec_from_file_location("tessel_abi_under_test", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main(argv):
    if len(argv) not in (2, 3):
        sys.stderr.write(__doc__)
        return 2
    abi = load_abi(argv[0])
    out = subprocess.run([argv[1]], check=True, stdout=subprocess.PIPE, text=True).stdout
    enum_values = {n: v for items in abi.ENUMS.values() for n, v, _ in items}
    passed = failed = 0
    seen_structs = set()
    seen_fields = set()

    def check(ok, what):
        nonlocal passed, failed
        if ok:
            passed += 1
        else:
            failed += 1
            print("ABI MISMATCH: " + what)

    for line in out.splitlines():
        parts = line.split()
        if parts[0] == "struct":
            name, size, align = parts[1], int(parts[2]), int(parts[3])
            cls = abi.STRUCTS.get(name)
            seen_structs.add(name)
            if cls is None:
                check(False, "struct %s is not declared" % name)
                continue
            check(ctypes.sizeof(cls) == size,
                  "sizeof(%s): C %d, ctypes %d" % (name, size, ctypes.sizeof(cls)))
            check(ctypes.alignment(cls) == align,
                  "alignment of %s: C %d, ctypes %d" % (name, align, ctypes.alignment(cls)))
        elif parts[0] == "field":
            sname, fname = parts[1].split(".")
            off, size = int(parts[2]), int(parts[3])
            seen_fields.add((sname, fname))
            cls = abi.STRUCTS.get(sname)
            desc = getattr(cls, fname, None) if cls else None
            if desc is None:
                check(False, "%s.%s is not declared" % (sname, fname))
                continue
            check(desc.offset == off and desc.size == size,
                  "%s.%s: C offset %d size %d, ctypes offset %d size %d"
                  % (sname, fname, off, size, desc.offset, desc.size))
        elif parts[0] == "enum":
            check(enum_values.get(parts[1]) == int(parts[2]),
                  "%s: C %s, generated %r" % (parts[1], parts[2], enum_values.get(parts[1])))
        elif parts[0] == "const":
            check(abi.CONSTANTS.get(parts[1]) == int(parts[2]),
                  "%s: C %s, generated %r" % (parts[1], parts[2], abi.CONSTANTS.get(parts[1])))
        else:
            check(False, "unexpected line %r" % line)
    # Nothing declared in Python that the compiler did not see.
    for name, fields in abi.FIELDS.items():
        check(name in seen_structs, "struct %s missing from the layout program" % name)
        for f in fields:
            check((name, f[0]) in seen_fields, "%s.%s missing from the layout program"
                  % (name, f[0]))
    if len(argv) == 3 and argv[2]:
        lib = ctypes.CDLL(argv[2])
        for fn in abi.FUNCTIONS:
            check(hasattr(lib, fn), "%s is declared in tessel.h but not exported by %s"
                  % (fn, argv[2]))
    print("%d passed, %d failed" % (passed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
