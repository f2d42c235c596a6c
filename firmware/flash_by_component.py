#!/usr/bin/env python3
"""Flash of an ARM ELF by component, from `objdump -d -l` line tables: each
instruction's bytes go to the source file of the innermost line objdump
names for it (inlined code counts where it was written), then files are
grouped into components. `.rodata` and the vector table are their own rows;
literal pools count with the code they follow.

Usage: flash_by_component.py ELF OBJDUMP SIZE
Prints `component bytes` rows, largest first, and their total (the flash
build.sh reports: vector table + text + rodata + data).
"""
import collections
import re
import subprocess
import sys

elf, objdump, size = sys.argv[1:4]

# First matching pattern names the component of a source path.
COMPONENTS = [
    ("command parsing (command.rs, Result/Option combinators, nom)",
     r"protocol/src/command\.rs|core/src/(result|option)\.rs|/nom-"),
    ("gimbal handler (firmware gimbal.rs)", r"firmware/src/gimbal\.rs"),
    ("device endpoint (device.rs)", r"protocol/src/device\.rs"),
    ("framer (framer.rs)", r"protocol/src/framer\.rs"),
    ("reply encoding (reply.rs, reply/shapes.rs)", r"protocol/src/reply(\.rs|/shapes\.rs)"),
    ("frame and hex (frame.rs, hex.rs, units.rs)", r"protocol/src/(frame|hex|units|address)\.rs"),
    ("memcpy/memset (compiler_builtins)", r"compiler[-_]builtins"),
    ("main loop and board (main.rs, serve.rs, common.rs, board.rs, cortex-m, PAC)", r"firmware/src/(main|serve|common|board)\.rs|cortex-m|lm3s6965"),
    ("other core (slices, integers, iterators)", r"/core/src/"),
]

dis = subprocess.run([objdump, "-d", "-l", "--no-show-raw-insn", elf], check=True, capture_output=True, text=True).stdout
line_re = re.compile(r"^(/\S+):\d+")
insn_re = re.compile(r"^\s+([0-9a-f]+):\s")
sections = {}
for row in subprocess.run([size, "-A", elf], check=True, capture_output=True, text=True).stdout.splitlines():
    parts = row.split()
    if len(parts) >= 3 and parts[0].startswith(".") and parts[1].isdigit():
        sections[parts[0]] = (int(parts[1]), int(parts[2]))
text_size, text_addr = sections.get(".text", (0, 0))
text_end = text_addr + text_size

source = "?"
starts = []  # (address, source file)
for row in dis.splitlines():
    m = line_re.match(row)
    if m:
        source = m.group(1)
        continue
    m = insn_re.match(row)
    if m:
        address = int(m.group(1), 16)
        if text_addr <= address < text_end:
            starts.append((address, source))
starts.sort()

bytes_by = collections.Counter()
for (address, src), (following, _) in zip(starts, starts[1:] + [(text_end, "")]):
    name = next((n for n, pattern in COMPONENTS if re.search(pattern, src)), "other")
    bytes_by[name] += following - address
bytes_by["vector table"] += sections.get(".vector_table", (0, 0))[0]
bytes_by["read-only data (.rodata, .data)"] += sections.get(".rodata", (0, 0))[0] + sections.get(".data", (0, 0))[0]

for name, n in bytes_by.most_common():
    print(f"{n:7d}  {name}")
print(f"{sum(bytes_by.values()):7d}  total")
