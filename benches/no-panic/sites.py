#!/usr/bin/env python3
"""Lists the call sites of the panic machinery in an ELF linked with a
panic handler that links (`--features report`), by source line of the
delaynav crate.

A function is panic machinery when it lies in `core` (or is the panic
handler) and can reach the handler through direct calls; a site is a direct
call or branch to one from anywhere else. Each site's inline chain (from
the line tables) is walked from the innermost frame outwards to the first
frame in the delaynav sources, which is the line to change; the innermost
frame and the panic function are shown beside it.

usage: sites.py ELF REPO_ROOT OBJDUMP ADDR2LINE"""
import collections
import re
import subprocess
import sys

elf, root, objdump, addr2line = sys.argv[1:5]
root = root.rstrip("/") + "/"
dis = subprocess.run([objdump, "-d", "-C", "--no-show-raw-insn", elf],
                     check=True, capture_output=True, text=True).stdout

func_re = re.compile(r"^([0-9a-f]+) <(.*)>:$")
call_re = re.compile(r"^\s*([0-9a-f]+):\s+(b|bl|blx|b\w\w|b\.w|bl\.w|b\w\w\.w)\s+0x[0-9a-f]+ <(.*)>")
# Any branch to a local address (conditional ones included), by target.
jump_re = re.compile(r"^\s*([0-9a-f]+):\s+(b\w*|cbn?z)\s+(?:\w+,\s*)?0x([0-9a-f]+) <")
insn_re = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)")
calls = collections.defaultdict(list)  # caller -> [(addr, callee)]
jumps_to = collections.defaultdict(list)  # target -> [branch addresses]
insns = []  # (addr, mnemonic) in address order
current = None
for line in dis.splitlines():
    m = func_re.match(line)
    if m:
        if not m.group(2).startswith("$"):  # not an ARM mapping symbol ($t, $d)
            current = m.group(2)
        continue
    m = insn_re.match(line)
    if m:
        insns.append((int(m.group(1), 16), m.group(2)))
    m = jump_re.match(line)
    if m:
        jumps_to[int(m.group(3), 16)].append(int(m.group(1), 16))
    m = call_re.match(line)
    if m and current and "+0x" not in m.group(3):
        calls[current].append((int(m.group(1), 16), m.group(3)))
insn_index = {addr: i for i, (addr, _) in enumerate(insns)}

# Every panic enters core::panicking (panic_fmt and friends; LTO may have
# inlined the handler, rust_begin_unwind, into them).
names = set(calls) | {c for cs in calls.values() for _, c in cs}
roots = {f for f in names if f.startswith("core::panicking::") or f.endswith("rust_begin_unwind")}
if not roots:
    print("no panic machinery in the image: no reachable panic")
    sys.exit(0)

reaches = set(roots)
changed = True
while changed:
    changed = False
    for caller, cs in calls.items():
        if caller not in reaches and any(c in reaches for _, c in cs):
            reaches.add(caller)
            changed = True
machinery = {f for f in reaches if f in roots or f.startswith("core::") or f.startswith("<core::")}

sites = [(addr, caller, callee) for caller, cs in calls.items() if caller not in machinery
         for addr, callee in cs if callee in machinery]
if not sites:
    print("no call into the panic machinery: no reachable panic")
    sys.exit(0)

# addr2line prints (function, file:line) pairs, innermost frame first.
def chain(addr):
    """(function, file:line) frames at `addr`, innermost first."""
    lines = subprocess.run([addr2line, "-e", elf, "-f", "-i", "-C", hex(addr)],
                           check=True, capture_output=True, text=True).stdout.splitlines()
    return [(lines[i], lines[i + 1]) for i in range(0, len(lines) - 1, 2)]


def ours(frames):
    """The innermost frame in the delaynav sources, if its line is known."""
    for fn, loc in frames:
        loc = re.sub(r" \(discriminator \d+\)$", "", loc)
        if loc.startswith(root + "src/") and not loc.endswith(":0"):
            return fn, loc[len(root):]
    return None


def strip_hash(name):
    """A readable function name: no hash, legacy-mangling escapes undone."""
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    for code, text in (("$LT$", "<"), ("$GT$", ">"), ("$C$", ","), ("$u20$", " "),
                       ("$u7b$", "{"), ("$u7d$", "}"), ("$RF$", "&"), ("..", "::")):
        name = name.replace(code, text)
    return re.sub(r"(^|::)_(<|\{)", r"\1\2", name)


def feeders(addr):
    """Branches into the straight run of instructions that ends with the
    panic call at `addr`. LTO merges the panic calls of a function into one
    cold block, whose own line is that of unrelated code; the branches into
    it carry the lines of the checks that fail."""
    found = []
    i = insn_index.get(addr)
    steps = 0
    while i is not None and i >= 0 and steps < 8:
        start, mnemonic = insns[i]
        if start != addr and (mnemonic in ("b", "b.w", "bx", "pop", "pop.w")
                              or mnemonic.startswith("bl")):
            break  # the run into the call starts after this instruction
        found += jumps_to.get(start, [])
        i -= 1
        steps += 1
    return found


by_line = collections.defaultdict(set)
for call_addr, caller, callee in sites:
    for addr in feeders(call_addr) or [call_addr]:
        frames = chain(addr)
        found = ours(frames)
        # Compiler-made code at the call may carry line 0: take the nearest
        # instruction before it that has a line in delaynav.
        back = 2
        while found is None and back <= 64:
            found = ours(chain(addr - back))
            back += 2
        inner = frames[0][1] if frames else "?"
        inner = re.sub(r"^.*/(rustlib/src/rust/library|registry/src/[^/]+|library)/", "", inner)
        panic = strip_hash(callee).split("::")[-1]
        key = (found[1], strip_hash(found[0])) if found else ("(no delaynav line)", strip_hash(caller))
        by_line[key].add((panic, inner))

print(f"{len(by_line)} panic site(s) reachable from the push API ({len(sites)} call instructions):")
for (loc, fn), details in sorted(by_line.items()):
    what = "; ".join(sorted(p if i.startswith(root) or i.startswith("src/") else f"{p} via {i}"
                            for p, i in details))
    print(f"  {loc}  in {fn}: {what}")
