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
Ownership cannot be borrowed: CLAIM returns a **nonce** chosen by the PLC (masked, so no
register ever shows it), and every command and heartbeat of the owner carries an **auth**
word computed from it, so a master that copies the owner's id from the readable registers is
refused (section 7). The owner's commands are acknowledged in registers of their own, so no
other master's command can hide them. A job ends COMPLETE only with every punch **at rest in
its band** (section 3, step 6), never because no punch happens to be moving.
"""

CONVENTIONS = """\
## 1. Conventions

- **Holding registers only.** Read with function 3, write with function 16; function 6
  (one register) is accepted too. Addresses are 0-based protocol addresses (mbpoll: `-0`).
  The map spans registers 0 to {last_address}.
- **Unit id**: 1 unless configured otherwise (1-247); the master's URL says which
  (`unit=N`). A request for another unit id is never acted on: the PLC gives no reply, or an
  exception (11 from a gateway, 4 from some stacks); mppf treats a timeout or any exception
  to its identity read as "not an mppf press PLC with unit id N".
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
  significant) of register `block + index // 16`. Setpoint registers past the matrix in use
  are ignored (a write there is stored, never checked nor counted); actual and fault-bit
  registers past the matrix read 0 and, being read-only, a write there is undone and counted.
- **Read-only registers** (access `ro`) are written by the PLC only: it rewrites them at
  every scan. A master write to one, or to a reserved register (the addresses between the
  fields, which read 0), is undone at the next scan and counted in `refused_writes`.
- **Master ids** are 32-bit numbers, never 0, chosen by each master (mppf draws a random
  one per connection and records it in its audit log). An id is a name, not a proof: the
  nonce and the auth words of section 7 are what make a master the owner.
"""

SCAN = """\
## 3. The scan

The PLC program runs in a cycle (its **scan**). `scan_time_max_ms` states the longest scan
period: the time from the start of one scan to the start of the next, at its longest (at most
{scan_time_max_ms} ms); a write is therefore acted on at most that long after it lands.
Whatever a master wrote lands in the registers at once; the program looks at it only in its
next scan, in this order:

1. **Inputs.** An open e-stop circuit latches fault ESTOP (state FAULT) in any state; the
   hardware has already cut the valves. With another fault already latched, `fault_code`
   keeps the first fault and the `estop` bit is set; RESET is refused (ESTOP_ACTIVE) while
   the e-stop is pressed. The remote-enable key switch is read.
2. **Setpoint guard.** The setpoint registers in use (`2 x rows x cols` per block) are
   compared with the PLC's own copy. If they changed: in IDLE, LOADED or VALIDATED the copy
   takes them, the state becomes LOADED and a validated job is dropped; in every other state
   the registers are written back from the copy and `refused_writes` and
   `refused_setpoint_writes` count the scan. A changed read-only or reserved register is
   restored and counted in `refused_writes` (once per scan).
3. **STOP.** `stop_request` not 0: `stop_count` + 1, `last_stop_master` = `stop_master`,
   `stop_cause` = STOP_REQUEST, `stop_request` = 0, and STOP is carried out (section 8).
4. **Heartbeat and lease.** The heartbeat registers ({hb_first}-{hb_last}) are compared with
   what they held at the previous scan; when they changed, the beat counts if
   `heartbeat_master` is the owner, `heartbeat_counter` is newer than the counter of the
   owner's last accepted beat (`(new - last) mod 65536` from 1 to 32767; any counter for the
   first beat after CLAIM) and `heartbeat_auth` is right (section 7); a beat that counts
   renews the lease. A lease not renewed for `watchdog_ms` ends in every state: no owner,
   the nonce forgotten; in EXECUTING fault WATCHDOG (the punches brake), in LOADED or
   VALIDATED the job is dropped (IDLE); in STOPPING the punches go on braking to STOPPED; in
   COMPLETE, STOPPED and FAULT the state stays. The key switch turned to local during
   EXECUTING stops the motion (STOPPING, `stop_cause` REMOTE_DISABLED).
5. **Mailbox.** A (`command_counter`, `command_master`, `command_auth`) triple other than
   that of the last command taken is one new command. The mailbox holds one command: a second
   command written before the scan overwrites the first, which is never taken nor
   acknowledged (a master writes its next command only after the acknowledgement of its
   last). Its refusals are tested in the order of the command table (section 5); the first
   that applies is its result, otherwise it is carried out (result ACCEPTED); an unknown
   code is BAD_COMMAND before any other check. Then `ack_counter`, `ack_master`,
   `ack_command` and `result_code` are written; a command that carried the owner's valid
   auth (and an accepted CLAIM) is also written to `owner_ack_counter`, `owner_ack_command`
   and `owner_result_code`. A refused command changes nothing but these registers: the state,
   a validated job and the lease stay as they were. A command taken is never carried out
   again. The scan that takes a CLAIM writes `command_crc` (the claim key) back to 0.
6. **Motion.** The punches move toward their **goal**: the setpoints of the last GO (before
   the first GO, the positions at power-on). A punch is **at rest** when its speed has stayed
   under `rest_speed` for `rest_time_ms`; it is **in its band** when |actual - goal| <=
   `position_tolerance`. EXECUTING becomes COMPLETE only when every punch is at rest AND in its
   band: "no punch moving" is not enough (in the scan of GO the valves may not have opened
   yet). EXECUTING with every punch at rest but one outside its band for
   `positioning_timeout_ms` latches STUCK_PUNCH with the fault bits of the punches outside
   their band. STOPPING becomes STOPPED when every punch is at rest (no band: a stopped motion
   ends short). A fault halts or brakes the punches; the press is at rest again when every
   punch is.
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
validates again with a new sequence. `validated_sequence` / `validated_crc` keep the token
through EXECUTING and COMPLETE (GO does not clear them; GO is accepted only in VALIDATED, so a
token starts one motion at most); STOP, RESET, a fault, a setpoint change and the end of a
lease in LOADED or VALIDATED set them to 0. RESET from FAULT clears any latched fault
(OVERPRESSURE and STUCK_PUNCH too) once the e-stop is released; a cause still present
latches its fault again at the next scan, and punches halted by STUCK_PUNCH stay where they
stopped (the next job moves them from there).
"""

COMMANDS = """\
## 5. Commands (the mailbox)

The master writes registers {mailbox_first}-{mailbox_last} in **one** function-16 request:
`command`, `command_counter` (a new value for every command, 1-65535), `command_master`
(its id), `command_crc` (the job's CRC for VALIDATE and GO, the claim key for CLAIM, 0
otherwise), `command_auth` (section 7) and `command_sequence` (the job's sequence for VALIDATE
and GO, 0 otherwise). The owner then reads the status block until `owner_ack_counter` is its
counter (with `owner_master` its id): `owner_result_code` is the result; a master that is not
the owner (before its CLAIM is accepted) looks at `ack_counter` / `ack_master` /
`result_code` instead. The shared `ack_*` registers show the last command of any master, and
any master may overwrite them a scan later (a NONE, say): the owner never relies on them.
After GO the owner also recognises its motion by `motion_sequence` / `motion_crc`. A master
that sees no acknowledgement within its timeout assumes its command was lost (mppf then
reports it; after GO it reads the state and sends STOP).

`checks` lists the refusals the PLC tests for the command, in the order it tests them.
"""

RESULTS = """\
## 6. Result codes and which refusal wins

`result_code` after a command. The table is in order of precedence: when several refusals
apply to one command, the PLC reports the one listed first (and tests only the ones in the
command's `checks`). So a command with master id 0 is BAD_MASTER whatever else is wrong; a
command from a master that does not own the PLC is NOT_OWNER even while the e-stop is
pressed; a command with the owner's id but not its auth is BAD_AUTH, also while the e-stop
is pressed; with the e-stop pressed every owner command but CLAIM is ESTOP_ACTIVE; a GO in the
wrong state is WRONG_STATE before the key switch (REMOTE_DISABLED) and the token
(TOKEN_MISMATCH) are looked at; a VALIDATE is SEQUENCE_REUSED before its CRC is computed,
and LIMIT only when the CRC matches.
"""

OWNERSHIP = """\
## 7. Ownership, nonce, lease, heartbeat and watchdog

- A master **claims** the PLC with CLAIM before it writes setpoints. It puts a **claim key**,
  a random 32-bit number other than 0, in `command_crc`. CLAIM is accepted when there is no
  live lease, or when it carries the owner's valid auth (a renewal); otherwise it is refused
  OWNED_BY_OTHER. On acceptance the PLC draws a new random 32-bit **nonce** (never 0), makes
  the claimer the owner (`owner_master`, status bit `owned`), writes `claim_reply` = nonce
  XOR claim key, and in the same scan writes `command_crc` back to 0. The claimer computes
  nonce = `claim_reply` XOR its key. No register ever holds the nonce itself.
- Every later command of the owner (RELEASE, VALIDATE, GO, RESET, and CLAIM to renew) and
  every heartbeat carries an **auth** word: the CRC-32 of section 9 over the 4 bytes of the
  nonce (most significant first) followed by the request's other registers, each high byte
  first, in address order: registers {mailbox_first}-{crc_last} and {command_sequence} for the mailbox (`command_auth`
  itself left out), {hb_first}-{hb_last_but_auth} for the heartbeat. A command is the owner's only if
  its `command_master` is the owner, its auth is right and its `command_counter` is newer than
  that of the owner's last command, its accepted CLAIM included (`(new - last) mod 65536`
  from 1 to 32767); otherwise
  the owner commands are refused BAD_AUTH (NOT_OWNER when the id is not the owner's at all).
  The counters' rule stops a replay of a recorded request.
- **Why:** master ids, `owner_master` and the validated token are readable by every master;
  without the nonce a master that copied them could send GO as the owner, or keep a dead
  owner's lease alive with beats in its name so that the watchdog never fires. The nonce
  reaches only the master that chose the claim key. This protects against masters that
  borrow ids, by mistake or by copying registers; it is not cryptography (Modbus has none:
  anyone who can sniff the network or write the claim key's registers within the CLAIM's
  scan sees everything), so the press network must still be kept to the press's masters.
- The owner writes `heartbeat_counter`, `heartbeat_master` (its id) and `heartbeat_auth` in
  one request ({hb_first}-{hb_last}) at least every quarter of `watchdog_ms` (mppf: every tenth,
  at most 250 ms). Each beat that counts (section 3, step 4) renews the **lease** (status bit
  `lease_ok`). Other masters' beats, and beats with a wrong auth or an old counter, never
  renew it.
- A lease not renewed for `watchdog_ms` ends the ownership and the nonce (section 3, step 4).
  During motion this is the **watchdog**: fault WATCHDOG, every punch brakes to a standstill.
  `watchdog_ms` = 0 means no watchdog and a lease that never lapses (test benches only: a
  press must have one).
- RELEASE is refused (WRONG_STATE) during EXECUTING and STOPPING: the owner keeps its lease,
  and its heartbeat, until the press is at rest. mppf releases the PLC when its work is done
  and nothing moves.
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
- IDLE, LOADED, VALIDATED, COMPLETE: STOPPED at once (the job is dropped); a punch still
  moving brakes;
- STOPPING, STOPPED, FAULT: the state stays; anything still moving brakes.

Every STOP request sets `stop_cause` to STOP_REQUEST, also in STOPPED and FAULT; faults never
change `stop_cause` (`fault_code` says which). A master that finds `stop_count` higher than
when it last looked knows someone stopped the press (`last_stop_master` says who); mppf tells
the operator and asks before it RESETs a STOPPED press.

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

VALIDATE checks, on the PLC's copy of the setpoints, that the CRC matches `command_crc`,
that every setpoint in use lies within `upper_min`..`upper_max` and `lower_min`..`lower_max`,
and two machine-safety checks of its own, whatever the master believes about the press:

- **Neighbour step** (NEIGHBOUR_STEP): for two neighbouring punches of one matrix (same row,
  adjacent columns, or same column, adjacent rows) the neighbour step is the smaller of two
  differences: that of their setpoints (the step pressed into a flat plate) and that of their
  moves, a move being the setpoint minus the punch's actual position at VALIDATE (the step
  pressed on from where the punches stand). Every neighbour step must be at most
  `dimpling_limit`: a job must be a lawful step from a flat plate or from the present shape
  (the first step of a new plate or section starts from flat, the next ones from the last).
- **Tip gap** (TIP_GAP): for every punch pair, upper setpoint minus lower setpoint (both are
  tip heights on the same z axis, so nothing else is subtracted) must be at least
  `tip_gap_min`.

A **parked** pair (upper and lower setpoints both within `position_tolerance` of the park
heights in the PLC's own press configuration) is left out of both checks. `dimpling_limit`
and `tip_gap_min` come from the PLC's configuration (its press file), never from a master.
When every check passes the PLC stores the token in `validated_sequence` / `validated_crc` (state VALIDATED). GO must
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
    ("rest", "`rest_speed` at most {rest_speed_max} (0.01 mm/s), `rest_time_ms` at least {rest_time_min_ms} ms",
     "after any trouble waits, heartbeat on, for `busy` clear AND actual positions still for the rest time"),
    ("reconnect", "accept a new connection at any time, also after dropping one",
     "after a lost link tries to reconnect (and read the status) for {reconnect_ms} ms, then STOP"),
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

State IDLE; no owner and no nonce (`claim_reply` 0); mailbox, both acknowledgements,
heartbeat and STOP registers 0; tokens and `last_sequence` 0; `refused_writes`,
`refused_setpoint_writes` and `stop_count` 0; setpoint registers equal to the actual
positions (the PLC's copy the same); no fault, unless the e-stop circuit is open (FAULT,
ESTOP); `remote_enabled` as the key switch stands; identity registers filled. A restart is a
power-on: ownership, nonce, tokens and sequences are lost, the punches stay where they are.
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
    ("a punch outside its band `positioning_timeout_ms` after every punch came to rest", "halt at once",
     "FAULT (STUCK_PUNCH)", "RESET"),
    ("PLC program stopped (PLC in STOP mode)", "outputs off: valves closed", "frozen",
     "mppf sees `plc_heartbeat` stale and reports it"),
]

SAFETY_NOTES = """\
Latched faults are never reset by mppf on its own: only an operator's `mppf reset`.
"""


# The conformance scenarios, the rules in one sentence each and the timed example of one job
# (section 10) are in their own module, re-exported here.
from mppf.drivers.regmap_prose_tail import (  # noqa: E402
    ANSWERS, CONFORMANCE, WIRE_EXAMPLE, WIRE_EXAMPLE_INTRO, WIRE_EXAMPLE_OUTRO)

__all__ = ["ANSWERS", "COMMANDS", "CONFORMANCE", "CONVENTIONS", "INTRO", "OWNERSHIP", "POWER_ON", "RESULTS",
           "SAFETY", "SAFETY_NOTES", "SAFETY_ROWS", "SCAN", "STATES", "STATE_NOTES", "STOP", "TIMING",
           "TIMING_NOTES", "TIMING_ROWS", "TOKEN", "WIRE_EXAMPLE", "WIRE_EXAMPLE_INTRO", "WIRE_EXAMPLE_OUTRO"]
