#!/usr/bin/env python3
"""Lists the panic machinery linked into an ARM ELF and the call sites that
pull it in, from `arm-none-eabi-objdump -d -C` (and addr2line for the source
lines, inlined frames included).

Panic machinery: every function that can reach `rust_begin_unwind` (the
panic handler) through calls or tail branches and is not our own code:
`core::panicking::*`, core's out-of-line failure helpers
(`slice_index_fail`, `len_mismatch_fail`, `unwrap_failed`, ...) and the
linker's outlined fragments that contain such a call. A call site is a call
or branch from any other function into that set.

Usage: panic_sites.py ELF OBJDUMP ADDR2LINE
Prints a report; exit status 0, the number of call sites on the last line
as `panic call sites: N`.
"""
import re
import subprocess
import sys

elf, objdump, addr2line = sys.argv[1:4]
dis = subprocess.run([objdump, "-d", "-C", "--no-show-raw-insn", elf], check=True, capture_output=True, text=True).stdout

header = re.compile(r"^([0-9a-f]+) <(.*)>:$")
# Calls and branches to a symbol: bl, blx, b, b.w, beq.w, cbz ... <sym> or <sym+0x..>.
branch = re.compile(r"^\s*([0-9a-f]+):\s+(bl|blx|b|b\.[nw]|b[a-z]{2}(?:\.[nw])?|cbn?z)\s+(?:r\d+,\s*)?[0-9a-f]+ <(.+)>\s*$")
offset = re.compile(r"\+0x[0-9a-f]+$")

calls = {}  # function -> [(address, target)]
current = None
for line in dis.splitlines():
    m = header.match(line)
    if m:
        current = m.group(2)
        calls.setdefault(current, [])
        continue
    m = branch.match(line)
    if m and current is not None:
        target = offset.sub("", m.group(3))
        if target != current:
            calls[current].append((m.group(1), target))


# Crates of the image other than core: a function whose name mentions one
# is code that can hold a call site (generic core code instantiated for our
# types, such as `<[u8; 263] as Index<Range<usize>>>::index`, is plumbing).
OURS = ("sagebrush", "gimbal::", "bench::", "nom::", "memchr::", "cortex_m", "tudelft", "main")


def is_ours(name):
    """Code of the firmware or of a crate it uses, as opposed to panic plumbing."""
    if "rust_begin_unwind" in name or name.startswith("OUTLINED_FUNCTION") or name.startswith("core::panicking"):
        return False
    return any(marker in name for marker in OURS)


# Panic plumbing: functions outside our crates that reach the panic handler
# without passing through our code (so `Reset` -> `main` is not plumbing).
machinery = {n for n in calls if "rust_begin_unwind" in n}
changed = True
while changed:
    changed = False
    for name, out in calls.items():
        if name not in machinery and not is_ours(name) and any(t in machinery for _, t in out):
            machinery.add(name)
            changed = True
machinery = sorted(machinery)
sites = [(a, f, t) for f, out in calls.items() if is_ours(f) for a, t in out if t in machinery]

print("panic machinery linked:", "none" if not machinery else "")
for name in machinery:
    print("  " + name)
for address, function, target in sorted(sites, key=lambda s: int(s[0], 16)):
    print(f"call site 0x{address} in {function} -> {target}")
    where = subprocess.run(
        [addr2line, "-e", elf, "-i", "-f", "-C", "-p", "0x" + address], capture_output=True, text=True
    ).stdout
    for frame in where.strip().splitlines():
        print("    " + frame.strip())
print(f"panic call sites: {len(sites)}")
