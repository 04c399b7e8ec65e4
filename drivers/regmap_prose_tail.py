"""The end of ``docs/register-map.md``'s prose: testing a PLC against mppf, the rules in one sentence each,
and the timed example of one job on the wire (section 10).

Part of :mod:`mppf.drivers.regmap_prose` (which re-exports these names); the ``{placeholders}``
are filled from the register map by :mod:`mppf.drivers.regmap_doc`. A test replays the driver
against the simulated PLC and checks that it writes exactly the requests of :data:`WIRE_EXAMPLE`.
"""

CONFORMANCE = """\
## 15. Testing your PLC against mppf

A PLC written from this page is tested with mppf's own driver (`mppf press`, `mppf status`,
`mppf stop`, `mppf reset` with `--plc tcp://your-plc:502?unit=1`) and a bare Modbus master
(mbpoll). Run every scenario below; each must end with the press at rest, a true message
and the documented exit code. The simulated PLC (`mppf sim --quirk ...`, docs/simulator.md)
shows what mppf does against a PLC that gets one of them wrong.

1. Identity and word order both ways; another `map_version` is refused (exit 3).
2. A job completed at your scan time; a job without travel (COMPLETE in the scan of its GO).
3. **At rest:** a PLC that opens its valves a scan after GO must not report COMPLETE in the
   GO scan (quirk `literal-complete`: mppf sees COMPLETE far sooner than the move can take,
   or punches out of their band, sends STOP, waits until the punches are still, exit 4).
4. Status bits one to three scans late (quirk `late-status:N`): jobs still complete.
5. GO refused without validation, with a stale token, after STOP, with the key switch in
   local; VALIDATE refused with a reused sequence, a wrong CRC, beyond the stroke limits, with
   a neighbour step above `dimpling_limit`, with a tip gap below `tip_gap_min`.
6. **Borrowed ids** (quirk `borrow-ids`): a master sending GO with the owner's id and the
   published token is refused BAD_AUTH; beats in the owner's name do not keep a dead owner's
   lease (kill -9 the pressing mppf: the watchdog stops the motion within `watchdog_ms`).
7. **A foreign NONE after GO** (quirk `none-after-go`): the owner still sees its GO in
   `owner_ack_counter` and follows the motion.
8. **A foreign STOP** during the motion (quirk `foreign-stop@T`): mppf reports who stopped
   the press; the next `mppf press` names the STOP and asks before its RESET (`--yes`
   answers; without a terminal it refuses, exit 4).
9. Setpoint writes during motion undone and counted (`refused_setpoint_writes`); mppf names
   them after the job.
10. A second master's CLAIM, VALIDATE, GO and RESET refused while another owns the PLC; STOP
    from a master that never claimed obeyed during motion.
11. Kill -9, SIGSTOP, SIGTERM and SIGHUP of `mppf press` during motion (the watchdog, or the
    driver's STOP, ends it); the link lost during motion (mppf reconnects for
    {reconnect_ms} ms and sends STOP); the e-stop refusing RESET until released; a stuck punch
    latching STUCK_PUNCH after `positioning_timeout_ms`.
12. `mppf status` and `mppf stop` beside a running job (STOP on the wire within 0.3 s of
    `mppf stop` starting).
"""

ANSWERS = """\
## 16. Rules in one sentence each

- **At rest**: a punch whose speed has stayed under `rest_speed` for `rest_time_ms`; COMPLETE
  needs every punch at rest and within `position_tolerance` of its goal (section 3, step 6).
- **`scan_time_max_ms`**: the longest time from the start of one scan to the start of the next.
- **Validated token**: kept through EXECUTING and COMPLETE, cleared by STOP, RESET, a fault, a
  setpoint change and a lease ending in LOADED or VALIDATED.
- **A lease ending** in STOPPING, COMPLETE, STOPPED or FAULT ends the ownership and changes
  nothing else (STOPPING still brakes to STOPPED); in EXECUTING it is fault WATCHDOG.
- **BAD_COMMAND**: an unknown command code, tested before every other check for every master.
- **A refused VALIDATE while VALIDATED** changes nothing: the old job stays validated.
- **RESET from FAULT** clears OVERPRESSURE and STUCK_PUNCH like any fault once the e-stop is
  released; a cause still present latches again at the next scan.
- **Positioning timeout**: `positioning_timeout_ms`, counted from the moment every punch came
  to rest with one outside its band.
- **`in_position` before the first GO**: set while every punch is at rest on its power-on
  position (the goal until the first GO).
- **`stop_cause`**: set to STOP_REQUEST by every STOP request in every state, to
  REMOTE_DISABLED by the key switch during motion, never by a fault.
- **Registers past the matrix**: setpoints there are ignored; actuals and fault bits there
  read 0 and a write to them is undone and counted.
- **Wrong unit id**: never acted on; no reply or an exception, both read by mppf as "not an
  mppf press PLC with unit id N".
- **A changed heartbeat**: the heartbeat registers differ from what the previous scan saw; the
  beat counts only with the owner's id, a newer counter and the right auth.
- **E-stop with another fault latched**: `fault_code` keeps the first fault, the `estop` bit
  is set and RESET is refused until the e-stop is released.
- **Status bits 9-15**: reserved, read 0, ignored by masters.
- **A second command in one scan**: the later write overwrites the earlier, which is never
  taken nor acknowledged.
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
    ("0", "R 0-{identity_last}", "identity: magic, map version 3, 4 x 6, scan 10 ms, limits, watchdog 1000 ms, "
     "tolerance, positioning timeout, rest threshold, dimpling limit, tip gap", "answers"),
    ("1", "R {status_first}-{status_last}", "state 1 IDLE, no owner, `last_sequence` 0", "answers"),
    ("2", "W {mailbox_first}-{mailbox_last}", "CLAIM: 1, counter 101, 0x1A2B 0x3C4D, claim key 0x5A5A 0x0F0F, "
     "auth (ignored), 0", "stores"),
    ("~8", "", "", "scan: CLAIM accepted, owner 0x1A2B3C4D, nonce drawn, `claim_reply` = nonce XOR key, "
     "`command_crc` = 0, ack 101 and owner ack 101, result 0"),
    ("10", "R {status_first}-{status_last}", "owner ack 101, result 0 ACCEPTED, owned, lease_ok, `claim_reply`: "
     "the master computes the nonce", "answers"),
    ("11", "W {hb_first}-{hb_last}", "heartbeat: counter 1, 0x1A2B 0x3C4D, auth (then every 100 ms)", "stores"),
    ("12", "W {upper_first}-{upper_last}", "upper setpoints, 24 x int32", "stores"),
    ("13", "W {lower_first}-{lower_last}", "lower setpoints, 24 x int32", "stores"),
    ("14", "R {upper_first}-{upper_last}, R {lower_first}-{lower_last}",
     "read back, compared by the master",
     "answers"),
    ("16", "W {mailbox_first}-{mailbox_last}", "VALIDATE: 3, counter 102, 0x1A2B 0x3C4D, CRC, auth, sequence 1",
     "stores"),
    ("~18", "",
     "",
     "scan: setpoints changed: LOADED; VALIDATE: auth, CRC, limits, neighbour step, tip gap pass, sequence 1 new: "
     "VALIDATED, owner ack 102 result 0"),
    ("20", "R {status_first}-{status_last}",
     "owner ack 102 ACCEPTED, state 3 VALIDATED, validated token (1, CRC)",
     "answers"),
    ("21", "R {uact_first}-{uact_last}, R {lact_first}-{lact_last}", "actual positions (start of the move)", "answers"),
    ("22", "W {mailbox_first}-{mailbox_last}", "GO: 4, counter 103, 0x1A2B 0x3C4D, CRC, auth, sequence 1", "stores"),
    ("~28", "", "", "scan: GO, token = validated: EXECUTING, motion token (1, CRC), owner ack 103 result 0"),
    ("30", "R {status_first}-{status_last}", "owner ack 103 ACCEPTED, state 4 EXECUTING, busy, our motion token",
     "answers"),
    ("80 ...", "R {status_first}-{status_last}", "every 50 ms: EXECUTING (actual positions every 250 ms)", "answers"),
    ("~20530", "", "", "scan: every punch at rest in its band for `rest_time_ms`: COMPLETE, in_position"),
    ("20560", "R {status_first}-{status_last}", "state 5 COMPLETE, motion token ours, in_position", "answers"),
    ("20561", "R {uact_first}-{uact_last}, R {lact_first}-{lact_last}",
     "actual positions: the master checks every punch itself",
     "answers"),
    ("20563", "W {mailbox_first}-{mailbox_last}",
     "RELEASE: 2, counter 104, 0x1A2B 0x3C4D, 0 0, auth, 0 (end of the job)",
     "stores"),
    ("~20568", "", "", "scan: RELEASE accepted, no owner, nonce forgotten; the state stays COMPLETE"),
    ("20570", "R {status_first}-{status_last}", "owner ack 104 ACCEPTED; the master stops its heartbeat", "answers"),
]

WIRE_EXAMPLE_OUTRO = """\
The next job of the same master starts with RESET (COMPLETE to IDLE), then upload,
VALIDATE with sequence 2, GO. A STOP from anyone during the motion is
`W {stop_first}-{stop_last}` = 1, its id: at the next scan the PLC writes `stop_request` back to 0
and the state becomes STOPPING, then STOPPED; the owner reads that and reports who stopped the
press.
"""
