"""The prose of ``docs/register-map.md``, written for a PLC programmer who never reads Python.

:mod:`mppf.drivers.regmap_doc` fills the ``{placeholders}`` from the register map (addresses,
codes, timing) and puts the generated tables between these sections, so the numbers in the
text cannot drift from ``register_map.toml``. :data:`WIRE_EXAMPLE` is the timed example of
one job on the wire; a test replays the driver against the simulated PLC and checks that it
writes exactly these requests in this order.
"""

INTRO = """\
# Register map of the press PLC (version {version})

This page is generated from `drivers/register_map.toml` (the tables) and
`drivers/regmap_prose.py` (the text) by `python -m mppf.drivers.regmap > docs/register-map.md`;
edit those, not this page. The mppf driver and the simulated PLC (`mppf sim`) both read the
TOML file. It is the complete contract between mppf (the **master**, a computer on the
shop-floor network) and the press PLC (the **PLC**, a Modbus server): a PLC written from this
page alone must work with mppf, and will be tested against it (section 15).

In one paragraph: the master writes the setpoints of every punch into holding registers,
then commands through a **mailbox** of registers that it writes in one request; the PLC
acts on what it finds at its next **scan** and answers in **acknowledgement registers**, never
by a Modbus exception. A job is started only by the master that **owns** the PLC, only for
the **job token** (sequence and CRC) it validated, and only with the key switch in remote;
the owner keeps its ownership alive with a **heartbeat**, and the PLC stops the motion when
the heartbeat goes stale. **STOP** has its own register and is obeyed from anyone, always.
"""

CONVENTIONS = """\
## 1. Conventions

- **Holding registers only.** Read with function 3, write with function 16; function 6
  (one register) is accepted too. Addresses are 0-based protocol addresses (mbpoll: `-0`).
  The map spans registers 0 to {last_address}.
- **Unit id**: 1 unless configured otherwise (1-247); the master's URL says which
  (`unit=N`). A PLC answers only requests to its own unit id (others: no reply, or exception
  11 from a gateway); mppf then reports "not an mppf press PLC with unit id N".
- **Exceptions**: the only Modbus exception the PLC sends is {illegal_address} (ILLEGAL DATA
  ADDRESS), for a request that reaches outside registers 0-{last_address} (and the standard
  ones for a malformed request). Every write inside the map is accepted by the PLC's
  Modbus server and stored at once; the PLC program judges it at its next scan, and every
  refusal is reported in registers (`result_code`, `refused_writes`), never by an exception.
- **One request is one unit.** The program must see a multi-register write completely or
  not at all, never half of it (copy writes into the program's memory between scans, or
  lock). The master relies on it for the mailbox, the heartbeat and STOP.
- **Positions** are signed int32 in 0.01 mm (`12345` = 123.45 mm), tip heights in press z.
- **32-bit values** take two registers in a **word order** configured on the PLC: `ABCD`
  (high word first) or `CDAB` (low word first); the bytes inside a register are always high
  byte first. Registers {magic_span} hold the **magic** 0x{magic:08X} ("MPPF"): the master reads
  them on connect and decodes them in both orders; the one that gives the magic is the PLC's
  order (ABCD: `0x4D50 0x5046`, CDAB: `0x5046 0x4D50`). Anything else: not an mppf PLC.
- **Punch index**: setpoint, actual and fault-bit blocks are in punch index order,
  `index = row * cols + col` (rows and columns counted from 0 here; the operator's messages
  count from 1), with `rows`/`cols` in registers {rows} and {cols}. Punch `index` uses
  registers `block + 2*index` and `+1`; its fault bit is bit `index % 16` (bit 0 = least
  significant) of register `block + index // 16`. Registers past the matrix in use are
  ignored (they may hold anything).
- **Read-only registers** (access `ro`) are written by the PLC only: it rewrites them at
  every scan. A master write to one, or to a reserved register (the addresses between the
  fields, which read 0), is undone at the next scan and counted in `refused_writes`.
- **Master ids** are 32-bit numbers, never 0, chosen by each master (mppf draws a random
  one per connection and records it in its audit log).
"""

SCAN = """\
## 3. The scan

The PLC program runs in a cycle (its **scan**, at most {scan_time_max_ms} ms, stated in
`scan_time_max_ms`). Whatever a master wrote lands in the registers at once; the program
looks at it only in its next scan, in this order:

1. **Inputs.** An open e-stop circuit latches fault ESTOP (state FAULT) in any state; the
   hardware has already cut the valves. The remote-enable key switch is read.
2. **Setpoint guard.** The setpoint registers in use (`2 x rows x cols` per block) are
   compared with the PLC's own copy. If they changed: in IDLE, LOADED or VALIDATED the copy
   takes them, the state becomes LOADED and a validated job is dropped; in every other state
   the registers are written back from the copy and `refused_writes` counts the scan. A
   changed read-only or reserved register is restored and counted too (once per scan).
3. **STOP.** `stop_request` not 0: `stop_count` + 1, `last_stop_master` = `stop_master`,
   `stop_request` = 0, and STOP is carried out (section 8).
4. **Heartbeat and lease.** A changed pair (`heartbeat_master`, `heartbeat_counter`) whose
   master is the owner renews the owner's lease. A lease not renewed for `watchdog_ms` ends:
   no owner; in EXECUTING fault WATCHDOG (the punches brake), in LOADED or VALIDATED the job
   is dropped (IDLE). The key switch turned to local during EXECUTING stops the motion
   (STOPPING, `stop_cause` REMOTE_DISABLED).
5. **Mailbox.** A (`command_counter`, `command_master`) pair other than that of the last
   command taken is one new command (at most one per scan). Its refusals are tested in the
   order of the command table (section 5); the first that applies is its result, otherwise it
   is carried out (result ACCEPTED). Then `ack_counter`, `ack_master`, `ack_command` and
   `result_code` are written. A refused command is taken too: the same pair is never
   carried out later.
6. **Motion.** The punches move toward the goal of the last GO. EXECUTING with every punch at
   rest becomes COMPLETE; STOPPING at rest becomes STOPPED. A positioning timeout latches
   STUCK_PUNCH with the punch's fault bit.
7. **Outputs.** Every read-only register is written: status, state, codes, tokens,
   counters, actual positions, fault bits; `plc_heartbeat` + 1.

A command written just after a scan started is acted on by the next one, so the master
sees its acknowledgement within two scans plus the reply time. The program never decides
inside a Modbus request.
"""

STATES = """\
## 4. States

`state` holds one of these codes. A state's **commands** are the mailbox commands it accepts
(any other is refused with WRONG_STATE); **setpoints** says what the guard of step 2 does
with a changed setpoint register. STOP (section 8) is obeyed in every state.
"""

STATE_NOTES = """\
Transitions in short: IDLE --setpoint change--> LOADED --VALIDATE--> VALIDATED --GO-->
EXECUTING --at rest--> COMPLETE --RESET--> IDLE. A setpoint change in VALIDATED goes back to
LOADED. STOP: EXECUTING --> STOPPING --at rest--> STOPPED; IDLE, LOADED, VALIDATED, COMPLETE
--> STOPPED at once. Any fault --> FAULT. RESET (owner) from IDLE, LOADED, VALIDATED, COMPLETE,
STOPPED or FAULT (cause removed) --> IDLE. RELEASE or a lost lease in LOADED or VALIDATED -->
IDLE. STOP and RESET always drop the validated job: no GO is possible until the owner
validates again with a new sequence.
"""

COMMANDS = """\
## 5. Commands (the mailbox)

The master writes registers {mailbox_first}-{mailbox_last} in **one** function-16 request:
`command`, `command_counter` (a new value for every command, 1-65535), `command_master`
(its id), `command_crc` and `command_sequence` (the job token for VALIDATE and GO, 0
otherwise). The PLC takes a pair (`command_counter`, `command_master`) once. The master then
reads the status block until `ack_counter` and `ack_master` are its own pair; `result_code`
is the result and `state` the state after it. A master that sees another pair acknowledged
after its timeout assumes its command was lost (mppf then reports it; after GO it sends STOP).

`checks` lists the refusals the PLC tests for the command, in the order it tests them.
"""

RESULTS = """\
## 6. Result codes and which refusal wins

`result_code` after a command. The table is in order of precedence: when several refusals
apply to one command, the PLC reports the one listed first (and tests only the ones in the
command's `checks`). So a command with master id 0 is BAD_MASTER whatever else is wrong; a
command from a master that does not own the PLC is NOT_OWNER even while the e-stop is
pressed; with the e-stop pressed every owner command but CLAIM is ESTOP_ACTIVE; a GO in the
wrong state is WRONG_STATE before the key switch (REMOTE_DISABLED) and the token
(TOKEN_MISMATCH) are looked at; a VALIDATE is SEQUENCE_REUSED before its CRC is computed,
and LIMIT only when the CRC matches.
"""

OWNERSHIP = """\
## 7. Ownership, lease, heartbeat and watchdog

- A master **claims** the PLC with CLAIM before it writes setpoints. CLAIM is accepted when
  there is no owner, or the claimer is the owner; while another master holds a live lease it
  is refused (OWNED_BY_OTHER). `owner_master` names the owner, status bit `owned` says there
  is one.
- VALIDATE, GO, RESET and RELEASE are accepted only from the owner (NOT_OWNER otherwise).
  The PLC cannot tell who wrote a setpoint register; a foreign write is caught by the job
  token (the CRC is the owner's, computed over what it wrote and read back) and by the rule
  that any setpoint change drops a validated job.
- The owner writes `heartbeat_master` (its id) and a new `heartbeat_counter` in one request
  ({hb_first}-{hb_last}) at least every quarter of `watchdog_ms` (mppf: every tenth, at most
  250 ms). Each scan that sees a changed pair with the owner's id renews the **lease**
  (status bit `lease_ok`). Beats of other masters are ignored (but overwrite the registers:
  only the owner should beat).
- A lease not renewed for `watchdog_ms` ends the ownership. During motion this is the
  **watchdog**: fault WATCHDOG, every punch brakes to a standstill. `watchdog_ms` = 0 means
  no watchdog and a lease that never lapses (test benches only: a press must have one).
- The owner gives the PLC back with RELEASE when its work is done (mppf does on closing).
- GO also needs the **remote-enable key switch** at the machine in remote (status bit
  `remote_enabled`), else REMOTE_DISABLED; turning it to local during motion stops the motion.
"""

STOP = """\
## 8. STOP

STOP has its own registers, never the mailbox, so that it cannot be lost behind another
master's command: any master writes `stop_request` = 1 and `stop_master` = its id (0 is
accepted too) in one request ({stop_first}-{stop_last}). At its next scan the PLC writes
`stop_request` back to 0, counts it in `stop_count`, records `last_stop_master` and:

- EXECUTING: STOPPING, every punch brakes at the acceleration limit; at rest STOPPED;
- IDLE, LOADED, VALIDATED, COMPLETE: STOPPED at once (the job is dropped);
- STOPPING, STOPPED, FAULT: the state stays; anything still moving brakes.

STOP is obeyed from anyone, in every state, without ownership. A master knows the PLC took
it when `stop_request` reads 0 again. After STOP only a RESET by the owner, then a new
VALIDATE with a new sequence, lets the press move again.
"""

TOKEN = """\
## 9. Setpoints and the job token

A **job** is the two setpoint blocks as written. Its **token** is the pair (sequence, CRC):

- **CRC**: the IEEE 802.3 CRC-32 (as zlib `crc32`: reflected polynomial 0xEDB88320, initial
  value 0xFFFFFFFF, final XOR 0xFFFFFFFF) over the bytes of the `2 * rows * cols` upper
  setpoint registers in use, in address order, followed by the `2 * rows * cols` lower ones;
  each register contributes two bytes, high byte first, exactly as stored (so the CRC depends
  on the word order). The CRC registers are uint32 in the PLC's word order.
- **Sequence**: 1-65535, new for every VALIDATE. The PLC accepts it only when it is newer than
  `last_sequence` (the newest it validated since power-on): `(sequence - last_sequence) mod
  65536` between 1 and 32767. A sequence is never accepted twice; 0 never.

VALIDATE checks, on the PLC's copy of the setpoints, that the CRC matches `command_crc` and
that every setpoint in use lies within `upper_min`..`upper_max` and `lower_min`..`lower_max`,
then stores the token in `validated_sequence` / `validated_crc` (state VALIDATED). GO must
carry exactly that token (TOKEN_MISMATCH otherwise); it copies it to `motion_sequence` /
`motion_crc` and moves every punch to the validated setpoints. The master follows the motion
until COMPLETE with its own token in `motion_sequence` / `motion_crc`.
"""

TIMING = """\
## 11. Timing requirements
"""

TIMING_ROWS = [
    ("scan time", "at most {scan_time_max_ms} ms, stated in `scan_time_max_ms`", "its waits scale with it"),
    ("command acknowledgement", "within {command_ack_scans} scans of the request's arrival",
     "waits 2 x reply timeout + 4 scans + 0.25 s"),
    ("reply time", "every request answered within {reply_time_max_ms} ms", "reply timeout 1 s (`timeout=` in the URL)"),
    ("watchdog", "`watchdog_ms` from {watchdog_min_ms} to {watchdog_max_ms} ms and at least 4 scans "
     "({watchdog_default_ms} ms recommended)",
     "heartbeat every tenth of it (at most 250 ms); refuses GO if a beat came later than a quarter"),
    ("STOP", "acted on at the next scan", "writes it in one request, never retried; confirms `stop_request` = 0"),
    ("PLC heartbeat", "`plc_heartbeat` + 1 every scan",
     "during motion, unchanged for 1 s = PLC program halted: STOP, report"),
    ("TCP connections", "at least {tcp_connections_min} at once; when none is free refuse the new one, never drop "
     "an open one", "one per mppf process: the pressing master (its heartbeat shares it), `mppf stop`, "
     "`mppf status`, a spare"),
]

TIMING_NOTES = """\
`mppf stop` and `mppf status` open their own connection beside a running `mppf press` and
close it within about a second; they must work while a job runs. mppf sends requests on one
connection one at a time (no pipelining) and retries reads and setpoint writes after a lost
reply, never commands, heartbeats or STOP. Over RTU the frames are separated by at least
3.5 character times of silence, as the standard requires.
"""

POWER_ON = """\
## 12. Power-on state

State IDLE; no owner; mailbox, acknowledgement, heartbeat and STOP registers 0; tokens and
`last_sequence` 0; `refused_writes` and `stop_count` 0; setpoint registers equal to the actual
positions (the PLC's copy the same); no fault, unless the e-stop circuit is open (FAULT,
ESTOP); `remote_enabled` as the key switch stands; identity registers filled. A restart is a
power-on: ownership, tokens and sequences are lost, the punches stay where they are.
"""

SAFETY = """\
## 13. What STOP, the watchdog and the e-stop do to the punches
"""

SAFETY_ROWS = [
    ("STOP request (any master)", "brake to a standstill at the acceleration limit", "STOPPING, then STOPPED",
     "owner: RESET, VALIDATE, GO"),
    ("key switch to local during motion", "brake to a standstill", "STOPPING, then STOPPED",
     "key to remote; RESET, VALIDATE, GO"),
    ("watchdog: the owner's heartbeat stale for `watchdog_ms` during motion", "brake to a standstill",
     "FAULT (WATCHDOG), no owner", "CLAIM, RESET, VALIDATE, GO"),
    ("e-stop pressed (any state)", "halt at once: the e-stop circuit closes the valves", "FAULT (ESTOP)",
     "release the e-stop; RESET (refused ESTOP_ACTIVE while pressed)"),
    ("overpressure", "halt at once", "FAULT (OVERPRESSURE)", "RESET"),
    ("a punch misses its setpoint (positioning timeout)", "halt at once; its fault bit set", "FAULT (STUCK_PUNCH)",
     "RESET"),
    ("PLC program stopped (PLC in STOP mode)", "outputs off: valves closed", "frozen",
     "mppf sees `plc_heartbeat` stale and reports it"),
]

SAFETY_NOTES = """\
Latched faults are never reset by mppf on its own: only an operator's `mppf reset`.
"""

CONFORMANCE = """\
## 15. What mppf checks of a PLC

A PLC written from this page is tested with mppf's own driver and a bare Modbus master:
identity and word order both ways; a job completed at its scan time; a job without travel
(COMPLETE in the scan of its GO); GO refused without validation, with a stale or foreign
token, after STOP, and with the key switch in local; VALIDATE refused with a reused sequence,
a wrong CRC and beyond the limits; setpoint writes during motion undone and counted; a
second master's CLAIM, VALIDATE, GO and RESET refused while another owns the PLC; STOP from
a master that never claimed obeyed during motion; the watchdog stopping the motion within
`watchdog_ms` when the master is killed; the e-stop refusing RESET until released; the
refusal precedence of section 6; `mppf status` and `mppf stop` beside a running job.
"""

# The timed example of section 10: (time, request, registers and values, what the PLC does).
# A test replays the driver and checks that its writes are these, in this order.
WIRE_EXAMPLE_INTRO = """\
## 10. One job on the wire

A 4 x 6 press, word order ABCD, scan time 10 ms, watchdog 1000 ms, master id 0x1A2B3C4D,
reply times about 1 ms; times in ms from the connection. `R a-b` is a function-3 read of
registers a to b, `W a-b` a function-16 write. The master's heartbeat (`W {hb_first}-{hb_last}`,
every 100 ms from the claim on) and its status polls (`R {status_first}-{status_last}`, every
5 ms while it waits for an acknowledgement, every 50 ms during motion) are shown once each.
"""

WIRE_EXAMPLE = [
    ("0", "R 0-15", "identity: magic, map version 2, 4 x 6, scan 10 ms, limits, watchdog 1000 ms", "answers"),
    ("1", "R {status_first}-{status_last}", "state 1 IDLE, no owner, `last_sequence` 0", "answers"),
    ("2", "W {mailbox_first}-{mailbox_last}", "CLAIM: 1, counter 101, 0x1A2B 0x3C4D, 0 0, 0", "stores"),
    ("~8", "", "", "scan: CLAIM accepted, owner 0x1A2B3C4D, ack 101, result 0"),
    ("10", "R {status_first}-{status_last}", "ack 101 of 0x1A2B3C4D, result 0 ACCEPTED, owned, lease_ok", "answers"),
    ("11", "W {hb_first}-{hb_last}", "heartbeat: 0x1A2B 0x3C4D, counter 1 (then every 100 ms)", "stores"),
    ("12", "W {upper_first}-{upper_last}", "upper setpoints, 24 x int32", "stores"),
    ("13", "W {lower_first}-{lower_last}", "lower setpoints, 24 x int32", "stores"),
    ("14", "R {upper_first}-{upper_last}, R {lower_first}-{lower_last}",
     "read back, compared by the master",
     "answers"),
    ("16", "W {mailbox_first}-{mailbox_last}", "VALIDATE: 3, counter 102, 0x1A2B 0x3C4D, CRC, sequence 1", "stores"),
    ("~18", "",
     "",
     "scan: setpoints changed: LOADED; VALIDATE: CRC and limits pass, sequence 1 new: VALIDATED, ack 102 result 0"),
    ("20", "R {status_first}-{status_last}",
     "ack 102 ACCEPTED, state 3 VALIDATED, validated token (1, CRC)",
     "answers"),
    ("21", "R {uact_first}-{uact_last}, R {lact_first}-{lact_last}", "actual positions (start of the move)", "answers"),
    ("22", "W {mailbox_first}-{mailbox_last}", "GO: 4, counter 103, 0x1A2B 0x3C4D, CRC, sequence 1", "stores"),
    ("~28", "", "", "scan: GO, token = validated: EXECUTING, motion token (1, CRC), ack 103 result 0"),
    ("30", "R {status_first}-{status_last}", "ack 103 ACCEPTED, state 4 EXECUTING, busy, our motion token", "answers"),
    ("80 ...", "R {status_first}-{status_last}", "every 50 ms: EXECUTING (actual positions every 250 ms)", "answers"),
    ("~20530", "", "", "scan: every punch at rest: COMPLETE, in_position"),
    ("20560", "R {status_first}-{status_last}", "state 5 COMPLETE, motion token ours, in_position", "answers"),
    ("20561", "R {uact_first}-{uact_last}, R {lact_first}-{lact_last}",
     "actual positions: the master checks every punch itself",
     "answers"),
    ("20563", "W {mailbox_first}-{mailbox_last}",
     "RELEASE: 2, counter 104, 0x1A2B 0x3C4D, 0 0, 0 (end of the job)",
     "stores"),
    ("~20568", "", "", "scan: RELEASE accepted, no owner; the state stays COMPLETE"),
    ("20570", "R {status_first}-{status_last}", "ack 104 ACCEPTED; the master stops its heartbeat", "answers"),
]

WIRE_EXAMPLE_OUTRO = """\
The next job of the same master starts with RESET (COMPLETE to IDLE), then upload,
VALIDATE with sequence 2, GO. A STOP from anyone during the motion is
`W {stop_first}-{stop_last}` = 1, its id: at the next scan the PLC writes `stop_request` back to 0
and the state becomes STOPPING, then STOPPED; the owner reads that and reports who stopped the
press.
"""
