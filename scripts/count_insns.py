#!/usr/bin/env python3
"""Instructions one call of an `extern "C" fn(input: *const T, output: *mut U)` executes in a
Cortex-M ELF: the figure docs/PERFORMANCE_MCU.md gives per forward pass. Deterministic (an
emulator, not a clock), so machines agree on it.

    python3 -m venv .venv && .venv/bin/pip install -r scripts/requirements-dev.txt
    .venv/bin/python scripts/count_insns.py \
        target/thumbv7em-none-eabihf/release/selftest-app selftest_forward --mix

The function runs in Unicorn (QEMU's CPU core) from its symbol until it returns, with
`r0` pointing at the input array, `r1` at the output array and the stack at the top of RAM.
An instruction inside an IT block whose condition fails executes (it takes its cycle) but
Unicorn does not report it; those are added back, so the count is what the CPU retires.

Bad input ends it with exit status 2 and one line (scripts/safe_input.py): the ELF a regular
file of at most 256 MiB, 32-bit little-endian Arm, its loadable segments inside it; at most
64 input and 64 output values; a function that has not returned after --max-insns
instructions (default 10,000,000, at most 1,000,000,000) is stopped and reported.
"""

import bisect
import collections
import io
import struct

from safe_input import Refusal, bounded_int, parser, quote, read_capped, run

PROG = "count_insns.py"
MAX_ELF_BYTES = 256 << 20
MAX_INSNS = 1_000_000_000
# The input and output arrays are 0x100 bytes apart.
MAX_VALUES = 64
EM_ARM = 40

CPUS = {
    "m0": "UC_CPU_ARM_CORTEX_M0",
    "m3": "UC_CPU_ARM_CORTEX_M3",
    "m4": "UC_CPU_ARM_CORTEX_M4",
    "m33": "UC_CPU_ARM_CORTEX_M33",
    "m7": "UC_CPU_ARM_CORTEX_M7",
}
TYPES = {"f32": ("f", 4), "i8": ("b", 1), "i16": ("h", 2), "i32": ("i", 4)}
RAM, RAM_SIZE = 0x2000_0000, 0x40_0000
INPUT, OUTPUT = RAM + 0x100, RAM + 0x200
# A return address inside mapped memory that no code occupies: the run stops there.
RETURN = 0x00FF_F000


def parse_args():
    p = parser(PROG, __doc__.split("\n\n")[0])
    p.add_argument("elf")
    p.add_argument("symbol", nargs="?", default="selftest_forward")
    p.add_argument("--in", dest="values", default="0.01,-0.02,0.03,0.04",
                   help="input array, comma-separated")
    p.add_argument("--in-type", default="f32", choices=TYPES)
    p.add_argument("--out-type", default="f32", choices=TYPES)
    p.add_argument("--nout", type=bounded_int(1, MAX_VALUES), default=2, help="output array length")
    p.add_argument("--max-insns", type=bounded_int(1, MAX_INSNS), default=10_000_000,
                   help="stop a function that has not returned after this many instructions")
    p.add_argument("--cpu", default="m4", choices=CPUS)
    p.add_argument("--mix", action="store_true", help="print mnemonics and functions")
    return p.parse_args()


def read_elf(elf_path):
    """The ELF file's bytes, checked to be a 32-bit little-endian Arm ELF before a parser
    sees them."""
    data = read_capped(elf_path, MAX_ELF_BYTES)
    if len(data) < 52 or data[:4] != b"\x7fELF":
        raise Refusal(f"{elf_path}: expected an ELF file, found {quote(data[:16])}")
    machine = struct.unpack_from("<H", data, 18)[0]
    if data[4] != 1 or data[5] != 1 or machine != EM_ARM:
        raise Refusal(f"{elf_path}: expected a 32-bit little-endian Arm ELF, found class "
                      f"{data[4]}, data encoding {data[5]}, machine {machine}")
    return data


def load(elf_path, data, cpu):
    from elftools.elf.elffile import ELFFile
    from unicorn import UC_ARCH_ARM, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
    from unicorn import arm_const as arm

    elf = ELFFile(io.BytesIO(data))
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(getattr(arm, CPUS[cpu]))
    uc.mem_map(0, 0x0100_0000)  # flash at 0, and the return page
    uc.mem_map(RAM, RAM_SIZE)
    mapped = [(0, 0x0100_0000), (RAM, RAM + RAM_SIZE)]
    for seg in elf.iter_segments():
        if seg["p_type"] != "PT_LOAD" or not seg["p_filesz"]:
            continue
        if seg["p_offset"] + seg["p_filesz"] > len(data):
            raise Refusal(f"{elf_path}: expected loadable segments inside the file, found "
                          f"{seg['p_filesz']} bytes at offset {seg['p_offset']} of {len(data)}")
        # The image where it is stored, and initialised data where the startup code would
        # have copied it; memory maps other than the micro:bit's (mps2-an505 runs code at
        # 0x10000000) get their regions mapped in 1 MiB blocks.
        for addr in {seg["p_paddr"], seg["p_vaddr"]}:
            lo = addr & ~0xF_FFFF
            hi = (addr + seg["p_filesz"] + 0xF_FFFF) & ~0xF_FFFF
            if not any(a <= lo and hi <= b for a, b in mapped):
                uc.mem_map(lo, hi - lo)
                mapped.append((lo, hi))
            uc.mem_write(addr, seg.data())
    symtab = elf.get_section_by_name(".symtab")
    if symtab is None:
        raise Refusal(f"{elf_path}: expected a symbol table, found none")
    funcs = sorted(
        (s["st_value"] & ~1, s.name) for s in symtab.iter_symbols()
        if s["st_info"]["type"] == "STT_FUNC"
    )
    return uc, funcs, symtab


def input_values(a):
    """The --in array, packed: at most MAX_VALUES numbers of --in-type."""
    code, _ = TYPES[a.in_type]
    try:
        xs = [float(v) if a.in_type == "f32" else int(v) for v in a.values.split(",")]
        if len(xs) > MAX_VALUES:
            raise ValueError
        return xs, struct.pack(f"<{len(xs)}{code}", *xs)
    except (ValueError, struct.error):
        raise Refusal(f"--in: expected at most {MAX_VALUES} numbers of type {a.in_type} "
                      f"separated by commas, found {quote(a.values)}")


def main():
    a = parse_args()
    xs, packed = input_values(a)
    data = read_elf(a.elf)
    # Every check that needs no emulator is done: now the emulator.
    from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
    from unicorn import UC_HOOK_CODE
    from unicorn import arm_const as arm

    uc, funcs, symtab = load(a.elf, data, a.cpu)
    found = symtab.get_symbol_by_name(a.symbol)
    if not found:
        raise Refusal(f"{a.elf}: expected a symbol {quote(a.symbol)}, found none")
    uc.mem_write(INPUT, packed)
    uc.reg_write(arm.UC_ARM_REG_R0, INPUT)
    uc.reg_write(arm.UC_ARM_REG_R1, OUTPUT)
    uc.reg_write(arm.UC_ARM_REG_SP, RAM + RAM_SIZE)
    uc.reg_write(arm.UC_ARM_REG_LR, RETURN | 1)

    seen = collections.Counter()
    uc.hook_add(UC_HOOK_CODE, lambda _uc, addr, size, _d: seen.update([(addr, size)]))
    uc.emu_start((found[0]["st_value"] & ~1) | 1, RETURN, count=a.max_insns)
    pc = uc.reg_read(arm.UC_ARM_REG_PC)
    if pc & ~1 != RETURN:
        raise Refusal(f"{a.symbol}: expected it to return within --max-insns {a.max_insns} "
                      f"instructions, found it still running at {pc:#x}")

    out_code, out_size = TYPES[a.out_type]
    ys = struct.unpack(f"<{a.nout}{out_code}", uc.mem_read(OUTPUT, out_size * a.nout))

    dis = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)

    def decode(addr):
        return next(dis.disasm(bytes(uc.mem_read(addr, 4)), addr), None)

    mnemonic = {k: (decode(k[0]).mnemonic if decode(k[0]) else "?") for k in seen}
    # Each IT block's conditional instructions: those not reported ran with a false condition.
    it_false = 0
    for (addr, size), count in seen.items():
        m = mnemonic[(addr, size)]
        if m.startswith("it") and len(m) <= 5:
            pc = addr + size
            for _ in range(len(m) - 1):
                ins = decode(pc)
                it_false += count - seen.get((pc, ins.size), 0)
                pc += ins.size
    total = sum(seen.values()) + it_false
    print(f"{a.symbol}({', '.join(map(str, xs))}) = [{', '.join(map(str, ys))}]")
    print(f"instructions: {total} ({a.cpu}; {it_false} of them IT-block instructions whose "
          f"condition failed)")
    if a.mix:
        mix = collections.Counter()
        for k, count in seen.items():
            mix[mnemonic[k]] += count
        print("mnemonics: " + ", ".join(f"{m} {c}" for m, c in mix.most_common(12)))
        starts = [f[0] for f in funcs]
        per_fn = collections.Counter()
        for (addr, _), count in seen.items():
            i = bisect.bisect_right(starts, addr) - 1
            per_fn[funcs[i][1] if i >= 0 else "?"] += count
        print("functions: " + ", ".join(f"{n} {c}" for n, c in per_fn.most_common(8)))


if __name__ == "__main__":
    run(PROG, main)
