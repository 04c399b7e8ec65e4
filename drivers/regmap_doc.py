"""The PLC programmer's description of the register map (``docs/register-map.md``), generated.

:func:`render_markdown` turns a :class:`mppf.drivers.regmap.RegisterMap` into the page;
``python -m mppf.drivers.regmap > docs/register-map.md`` writes the packaged map's.
"""

from __future__ import annotations

_INTRO = """\
# Register map of the press PLC

This page is generated from `drivers/register_map.toml` by
`python -m mppf.drivers.regmap > docs/register-map.md`; edit the TOML, not this page.
The mppf driver and the simulated PLC (`mppf sim`) both read that file.

## Conventions
- Everything is a **holding register** (read: function 3; write: function 16, function 6
  for single registers). Addresses are 0-based protocol addresses (mbpoll: `-0`).
- Positions are **signed int32 in 0.01 mm** (`12345` = 123.45 mm), tip heights in press z.
- 32-bit values use two registers in a **word order** configured on the PLC: `ABCD`
  (high word first) or `CDAB` (low word first); the bytes inside a register are always
  high byte first. Registers {magic_span} hold the **magic** 0x{magic:08X} ("MPPF"): the master reads
  them on connect and decodes them in both orders; the one that gives the magic is the
  PLC's order (ABCD: `0x4D50 0x5046`, CDAB: `0x5046 0x4D50`). Anything else: not an mppf PLC.
- Setpoint, actual and fault-bit blocks are in **punch index** order,
  `index = row * cols + col` (row-major, packed), with `rows`/`cols` the press size in
  registers {rows} and {cols}. Punch `index` uses registers `block + 2*index` and `+1`; its fault bit
  is bit `index % 16` (bit 0 = least significant) of register `block + index // 16`.
  Registers past the matrix in use are ignored.
- Registers marked **ro** may only be read by the master: a write that touches one is
  refused with exception {read_only} (ILLEGAL DATA ADDRESS) and nothing of that write is applied;
  so is a write to the unused registers between the fields (they read as 0).

## Handshake of a press step
1. **Upload**: the master writes the upper and lower setpoint blocks (chunks of at most
   {max_write} registers, so no int32 is split). Any write to a setpoint register clears
   the `data_valid` bit.
2. **Verify**: the master reads every written register back and compares.
3. **Validate**: the master writes `setpoint_crc` and `job_sequence` in one request
   (registers {job_first}-{job_last}, CRC first). On the write that contains `job_sequence` the PLC
   computes the CRC of its setpoint registers (below) and checks every setpoint against
   its own stroke limits (`upper_min`...`lower_max`). If both pass it stores the
   sequence in `acknowledged_sequence` and sets `data_valid`; otherwise it refuses the
   write with exception {refused} (ILLEGAL DATA VALUE) and puts the reason
   (`CRC_MISMATCH`, `LIMIT`; `SEQUENCE_MISMATCH` for sequence 0) in `refusal_code`.
4. **GO**: the master writes `command` = GO and `command_arg` = the job sequence in one
   request. The PLC accepts only if there is no e-stop, no latched fault, no motion in
   progress, the CRC still matches the setpoint registers (a foreign write since
   validation is caught here), every setpoint is within limits, `command_arg` equals
   `acknowledged_sequence` and `data_valid` is set. Otherwise it refuses with exception
   {refused} and the reason in `refusal_code`; nothing moves. A GO repeating the sequence of
   the motion in progress is accepted and does nothing (a retried GO cannot start a
   second motion).
5. **Follow**: the master polls `status_word` until `busy` clears, then reads the actual
   blocks and checks them against the setpoints. `in_position` is set when motion has
   ended and every punch is within the PLC's position tolerance.

**STOP** is always accepted and decelerates every punch to a standstill. **RESET**
clears a latched fault and the per-punch fault bits; it is refused (`ESTOP_ACTIVE`)
while the e-stop is still pressed. After a refused write, `refusal_code` holds the
reason until the next accepted command.

## Watchdog
The master changes `master_heartbeat` (any new value) at least every half watchdog
time. The PLC sets `remote` while the heartbeat changes within its watchdog time. If
the heartbeat goes stale **during motion** (no change for the watchdog time, counted from
the later of the last change and the GO), the PLC brakes every punch and latches fault
`WATCHDOG`.

## Setpoint CRC
`setpoint_crc` is the IEEE 802.3 CRC-32 (as zlib `crc32`: reflected polynomial
0xEDB88320, initial value 0xFFFFFFFF, final XOR 0xFFFFFFFF) over the bytes of the
`2 * rows * cols` upper setpoint registers in use, in address order, followed by the
`2 * rows * cols` lower setpoint registers in use; each register contributes two bytes,
high byte first, exactly as written (so the CRC depends on the word order). The CRC
itself is a uint32 in the PLC's word order.
"""


def render_markdown(rmap) -> str:
    """The markdown page of register map ``rmap`` (a :class:`~mppf.drivers.regmap.RegisterMap`)."""
    lines = [
        _INTRO.format(
            read_only=rmap.exceptions["read_only"],
            refused=rmap.exceptions["refused"],
            max_write=rmap.max_write_registers,
            magic_span=f"{rmap['magic'].address}-{rmap['magic'].end - 1}",
            magic=rmap.magic,
            rows=rmap["rows"].address,
            cols=rmap["cols"].address,
            job_first=min(rmap["setpoint_crc"].address, rmap["job_sequence"].address),
            job_last=max(rmap["setpoint_crc"].end, rmap["job_sequence"].end) - 1,
        ),
        "## Registers",
        f"Map version {rmap.version}, magic 0x{rmap.magic:08X}, up to {rmap.max_rows} x "
        f"{rmap.max_cols} punches per matrix, one count = {rmap.count_mm} mm.",
        "",
        "| address | count | name | type | access | description |",
        "|---:|---:|---|---|---|---|",
    ]
    for f in rmap.fields.values():
        span = f"{f.address}" if f.count == 1 else f"{f.address}-{f.end - 1}"
        lines.append(f"| {span} | {f.count} | `{f.name}` | {f.type} | {f.access} | {f.description} |")
    lines += ["", "## Commands", "", "| code | command |", "|---:|---|"]
    lines += [f"| {code} | {name} |" for name, code in rmap.commands.items()]
    lines += ["", "## Status bits (`status_word`)", "", "| bit | name |", "|---:|---|"]
    lines += [f"| {bit} | `{name}` |" for name, bit in sorted(rmap.status_bits.items(), key=lambda kv: kv[1])]
    lines += [
        "",
        "## Fault codes",
        "",
        "`fault_code` holds latched faults (kind *fault*: motion stopped, RESET needed);",
        "`refusal_code` holds the reason of the last refused write (kind *refusal*).",
        "",
        "| code | name | kind | meaning |",
        "|---:|---|---|---|",
    ]
    lines += [f"| {fc.code} | {fc.name} | {fc.kind} | {fc.text} |" for fc in rmap.fault_codes.values()]
    lines += [
        "",
        "## Modbus exception replies",
        "",
        "| code | when |",
        "|---:|---|",
        f"| {rmap.exceptions['read_only']} | a write touches a read-only or unused register |",
        f"| {rmap.exceptions['refused']} | a command or the job block is refused (reason in `refusal_code`) |",
        "",
    ]
    return "\n".join(lines)
