"""Run-level energy accounting from a variant's metrics rows (docs/DESIGN.md "Energy"): the total at the
start and the end, its largest rise from one frame to the next, its change across every fracture event,
and the frames where it rose by more than `VIOLATION` of the frame's total although no driving boundary
acted (MPM with APIC transfers is dissipative: a closed system's energy only goes down).

A frame where a moving grip, a velocity override or an impulse region acted (`energy_driven`) is not part
of a closed system: its rise is work done by the driver, never a violation. The energy of a frame is the
row's `energy_total`; changes are fractions of the larger of the two totals (for a rise, the frame's own).
"""

from __future__ import annotations

from typing import Optional

from ..sim.diagnostics.energy import relative_change

VIOLATION = 0.01  # a rise above this fraction of the frame's total, in a frame without drivers
MAX_LISTED = 8  # events and violations written out in summary.md (summary.json has them all)


def _step(a: dict, b: dict) -> dict:
    """The change of the total from row a to row b (the frame b)."""
    ea, eb = a["energy_total"], b["energy_total"]
    return {"frame": b["frame"], "delta": eb - ea, "fraction": relative_change(ea, eb)}


def energy_summary(rows: list) -> Optional[dict]:
    """{initial_total, final_total [J], max_increase (frame, delta [J], fraction; None if it never rose),
    driven_frames, closed, events (per latch: frame, latches, delta, fraction, then the same for the next
    frame, the first simulated with the new topology: next_delta, next_fraction; driven), violations
    (frame, delta, fraction)} of one variant's rows, or None without energy rows."""
    rows = [r for r in rows if r.get("energy_total") is not None]
    if not rows:
        return None
    steps = [(b, _step(a, b)) for a, b in zip(rows, rows[1:])]
    rises = [s for _, s in steps if s["delta"] > 0]
    driven = sum(1 for r in rows if r.get("energy_driven"))
    events = []
    for i, (row, step) in enumerate(steps):
        prev_latches = rows[i].get("latches", 0)
        if row.get("latches", 0) > prev_latches:
            after = steps[i + 1][1] if i + 1 < len(steps) else None
            events.append(
                {
                    "frame": row["frame"],
                    "latches": row["latches"],
                    "delta": step["delta"],
                    "fraction": step["fraction"],
                    "next_delta": after["delta"] if after else None,
                    "next_fraction": after["fraction"] if after else None,
                    "driven": bool(row.get("energy_driven")),
                }
            )
    violations = [s for row, s in steps if s["fraction"] > VIOLATION and not row.get("energy_driven")]
    return {
        "initial_total": rows[0]["energy_total"],
        "final_total": rows[-1]["energy_total"],
        "max_increase": max(rises, key=lambda s: s["delta"]) if rises else None,
        "driven_frames": driven,
        "closed": driven == 0,
        "events": events,
        "violations": violations,
    }


def _pct(fraction: Optional[float]) -> str:
    return "—" if fraction is None else f"{100 * fraction:+.2f} %"


def energy_line(variant: str, e: dict) -> str:
    """One summary.md bullet for a variant's energy summary."""
    rise = e["max_increase"]
    parts = [
        f"**{variant}**: E {e['initial_total']:.4g} J → {e['final_total']:.4g} J",
        f"largest rise {_pct(rise['fraction'])} (frame {rise['frame']})" if rise else "never rose",
    ]
    for ev in e["events"][:MAX_LISTED]:
        parts.append(
            f"event {ev['latches']} at frame {ev['frame']}{' (driven)' if ev['driven'] else ''}: "
            f"ΔE = {_pct(ev['fraction'])} "
            f"(next frame {_pct(ev['next_fraction'])})"
        )
    if len(e["events"]) > MAX_LISTED:
        parts.append(f"{len(e['events']) - MAX_LISTED} more events in summary.json")
    if e["closed"]:
        parts.append("closed system")
    else:
        parts.append(
            f"driven boundaries act in {e['driven_frames']} frame(s): not a closed system (rises there are work)"
        )
    if e["violations"]:
        listed = ", ".join(f"frame {v['frame']} {_pct(v['fraction'])}" for v in e["violations"][:MAX_LISTED])
        parts.append(f"**VIOLATION: energy rose by over {VIOLATION:.0%} without drivers in {listed}**")
    return "- " + "; ".join(parts)


def energy_markdown(summaries: list) -> str:
    """The summary.md section: one bullet per variant with energy rows ("" if none has them)."""
    lines = [energy_line(s["variant"], s["energy"]) for s in summaries if s.get("energy")]
    if not lines:
        return ""
    head = (
        "\n## Energy\n\nTotal = kinetic + gravitational (zero at the grid corner lowest along g) + elastic. "
        f"Changes are fractions of the frame's total; a rise over {VIOLATION:.0%} in a frame without a driving "
        "boundary (moving grip, velocity override, impulse) is a violation.\n\n"
    )
    return head + "\n".join(lines) + "\n"


def energy_warning(summaries: list) -> Optional[str]:
    """One line naming every variant whose energy rose over the threshold without drivers, or None."""
    bad = []
    for s in summaries:
        v = (s.get("energy") or {}).get("violations") or []
        if v:
            worst = max(v, key=lambda x: x["fraction"])
            bad.append(
                f"{s['variant']} in {len(v)} frame(s), worst {_pct(worst['fraction'])} at frame {worst['frame']}"
            )
    if not bad:
        return None
    return f"total energy rose by over {VIOLATION:.0%} in a frame without driving boundaries: " + "; ".join(bad)
