"""The PLC programmer's description of the register map (``docs/register-map.md``), generated.

:func:`render_markdown` turns a :class:`mppf.drivers.regmap.RegisterMap` into the page: the
tables (registers, states, commands, results, status bits, faults, stop causes, the timing
values) come from ``register_map.toml``, the text from :mod:`mppf.drivers.regmap_prose` with
its numbers filled in from the map. ``python -m mppf.drivers.regmap > docs/register-map.md``
writes the packaged map's.
"""

from __future__ import annotations

from mppf.drivers import regmap_prose as prose

EXAMPLE_ROWS, EXAMPLE_COLS = 4, 6  # the press of the wire example


def _values(rmap) -> dict:
    """The placeholders of the prose."""
    n = rmap.words_in_use(EXAMPLE_ROWS, EXAMPLE_COLS)

    def first_last(prefix: str, first: str, last: str) -> dict:
        a, count = rmap.span(first, last)
        return {f"{prefix}_first": a, f"{prefix}_last": a + count - 1}

    values = {
        "version": rmap.version, "last_address": rmap.total_registers - 1, "illegal_address": rmap.illegal_address,
        "magic": rmap.magic, "magic_span": f"{rmap['magic'].address}-{rmap['magic'].end - 1}",
        "rows": rmap["rows"].address, "cols": rmap["cols"].address,
        **first_last("mailbox", "command", "command_sequence"),
        **first_last("hb", "heartbeat_counter", "heartbeat_auth"),
        **first_last("stop", "stop_request", "stop_master"),
        **first_last("status", "stop_request", "refused_setpoint_writes"),
        **first_last("auth", "command_auth", "command_auth"),
        **first_last("crc", "command_crc", "command_crc"),
        "hb_last_but_auth": rmap["heartbeat_auth"].address - 1,
        "identity_last": max(f.end for f in rmap.group("identity")) - 1,
        **{name: rmap[name].address for name in ("command_sequence", "heartbeat_master", "claim_reply",
                                                  "owner_ack_counter")},
        **rmap.timing,
    }
    for key, block in (("upper", "upper_setpoints"), ("lower", "lower_setpoints"), ("uact", "upper_actuals"),
                       ("lact", "lower_actuals")):
        values[f"{key}_first"], values[f"{key}_last"] = rmap[block].address, rmap[block].address + n - 1
    return values


def _table(header: list[str], rows, align: str | None = None) -> list[str]:
    align = align or "|".join("---" for _ in header)
    lines = ["| " + " | ".join(header) + " |", f"|{align}|"]
    lines += ["| " + " | ".join(str(cell).replace("|", "\\|") for cell in row) + " |" for row in rows]
    return lines + [""]


def wire_example(rmap) -> list[tuple[str, str, str, str]]:
    """The rows of the timed example of section 10, with the map's addresses filled in."""
    values = _values(rmap)
    return [tuple(cell.format(**values) for cell in row) for row in prose.WIRE_EXAMPLE]


def render_markdown(rmap) -> str:
    """The markdown page of register map ``rmap`` (a :class:`~mppf.drivers.regmap.RegisterMap`)."""
    values = _values(rmap)

    def text(block: str) -> list[str]:
        return [block.format(**values)]

    def span(f) -> str:
        return f"{f.address}" if f.count == 1 else f"{f.address}-{f.end - 1}"

    lines = text(prose.INTRO) + text(prose.CONVENTIONS)
    lines += ["## 2. Registers", "",
              f"Map version {rmap.version}, magic 0x{rmap.magic:08X}, up to {rmap.max_rows} x {rmap.max_cols} punches "
              f"per matrix, one count = {rmap.count_mm} mm. Addresses not listed are reserved (read 0).", ""]
    lines += _table(["address", "count", "name", "type", "access", "group", "description"],
                    [(span(f), f.count, f"`{f.name}`", f.type, f.access, f.group, f.description)
                     for f in rmap.fields.values()], "---:|---:|---|---|---|---|---")
    lines += text(prose.SCAN) + text(prose.STATES)
    lines += _table(["code", "state", "entered when", "setpoint writes", "commands accepted"],
                    [(s.code, s.name, s.text, "taken (state LOADED)" if s.setpoints == "accept"
                      else "undone and counted", ", ".join(s.commands)) for s in rmap.states],
                    "---:|---|---|---|---")
    lines += text(prose.STATE_NOTES) + text(prose.COMMANDS)
    lines += _table(["code", "command", "from", "arguments", "does", "checks (in this order)"],
                    [(c.code, c.name, c.from_states, c.arguments, c.text, ", ".join(c.checks))
                     for c in rmap.commands], "---:|---|---|---|---|---")
    lines += text(prose.RESULTS)
    lines += _table(["code", "result", "meaning"], [(r.code, r.name, r.text) for r in rmap.results], "---:|---|---")
    lines += text(prose.OWNERSHIP) + text(prose.STOP) + text(prose.TOKEN) + text(prose.WIRE_EXAMPLE_INTRO)
    lines += _table(["t (ms)", "request", "registers, values", "PLC"], wire_example(rmap), "---:|---|---|---")
    lines += text(prose.WIRE_EXAMPLE_OUTRO) + text(prose.TIMING)
    lines += _table(["what", "requirement", "mppf's side"],
                    [tuple(cell.format(**values) for cell in row) for row in prose.TIMING_ROWS])
    lines += text(prose.TIMING_NOTES) + text(prose.POWER_ON) + text(prose.SAFETY)
    lines += _table(["event", "the punches", "state after", "to move again"], prose.SAFETY_ROWS)
    lines += text(prose.SAFETY_NOTES)
    lines += ["## 14. Status bits, fault codes, stop causes", "", "`status_word` (bit 0 = least significant):", ""]
    lines += _table(["bit", "name", "set when"],
                    [(bit, f"`{name}`", rmap.status_texts[name])
                     for name, bit in sorted(rmap.status_bits.items(), key=lambda kv: kv[1])], "---:|---|---")
    lines += ["`fault_code`: a latched fault puts the PLC in FAULT until RESET.", ""]
    lines += _table(["code", "fault", "the punches", "meaning"],
                    [(f.code, f.name, f.punches, f.text) for f in rmap.faults], "---:|---|---|---")
    lines += ["`stop_cause`: why the PLC stopped last.", ""]
    lines += _table(["code", "cause", "meaning"], [(c.code, c.name, c.text) for c in rmap.stop_causes], "---:|---|---")
    lines += text(prose.CONFORMANCE) + text(prose.ANSWERS)
    return "\n".join(lines).rstrip("\n") + "\n"
