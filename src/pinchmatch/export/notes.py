"""The one-line notes that close a run's summary: what a person should know about the answers as a
whole (upside-down placements, objects that do not rest on their prop's table or are pinched from
behind, props that serve as well, what the redirection did, props from scans whose scale nobody
measured). Each reads the rows or records the run
kept and returns a line, or None when there is nothing to say."""

from __future__ import annotations

from ..config import FAR_SIDE_MIN_ELEVATION_DEG, REST_TOLERANCE_MM


def flipped_note(rows: list[tuple], settings: dict) -> str | None:
    """How many placements of a matches table turn their virtual object upside down, and the option
    that keeps them upright (None when none does, or the run already keeps them upright)."""
    column = rows[0].index("flipped")
    flipped = sum(r[column] == "F" for r in rows[1:])
    if not flipped or settings.get("keep_upright"):
        return None
    return (f"{flipped} of {len(rows) - 1} placements turn the virtual object upside down (F); "
            "--keep-upright keeps every one upright, at some cost")



def rest_note(rests: list[tuple]) -> str | None:
    """How many of the objects shown on a standing prop could not rest on its table (more than
    ``REST_TOLERANCE_MM`` below or above it) and by how much, or None when every one rests (or none
    is shown)."""
    off = sorted(((v, g) for v, g in rests if abs(g) > REST_TOLERANCE_MM), key=lambda r: -abs(r[1]))
    if not off:
        return None
    shown = "; ".join(f"{v} {g:+.1f} mm" for v, g in off[:6]) + (f"; and {len(off) - 6} more"
                                                                 if len(off) > 6 else "")
    return (f"{len(off)} of {len(rests)} objects shown on a standing prop do not rest on its table "
            "within "
            f"{REST_TOLERANCE_MM:g} mm: no pinch found that rests feels better by what the gap "
            "costs (rest_gap_mm in "
            f"matches.json; - below the table, + above it; --rest-float-mm-per-jnd): {shown}")



def comfort_note(approaches: list[tuple]) -> str | None:
    """Which objects are pinched from the user's far side lower than ``FAR_SIDE_MIN_ELEVATION_DEG``:
    their prop offers no pinch reached from the user's side (None when every approach is
    comfortable)."""
    far = [(v, e, a) for v, e, a in approaches if a is not None and a > 90.0 and e
           < FAR_SIDE_MIN_ELEVATION_DEG]
    if not far:
        return None
    shown = "; ".join(f"{v} ({a:.0f} deg from the user, {e:.0f} deg up)" for v, e, a in far[:6])
    return (f"{len(far)} of {len(approaches)} objects are pinched from behind their prop, lower "
            "than "
            f"{FAR_SIDE_MIN_ELEVATION_DEG:g} deg: the prop offers no pinch reached from the user's "
            f"side (--user-at, docs/method.md): {shown}")



def equivalent_note(equivalents: list[tuple]) -> str | None:
    """Which objects another prop serves as well as their own (within 0.1 JND or 5 %), or None."""
    if not equivalents:
        return None
    shown = "; ".join(f"{v}: {t} ~ {', '.join(others)}" for v, t, others in equivalents[:6])
    more = f"; and {len(equivalents) - 6} more" if len(equivalents) > 6 else ""
    return (f"{len(equivalents)} objects are served as well by another prop (within 0.1 JND or 5 "
            f"%, equivalent_tangibles in matches.json): {shown}{more}")



def reference_note(references: list[tuple]) -> str | None:
    """Why ``ref_cost`` is null, where it is: ``references`` [(virtual, the reason or None)] of the
    matched."""
    missing = [(name, why) for name, why in references if why]
    if not missing:
        return None
    reasons: dict[str, list[str]] = {}
    for name, why in missing:
        reasons.setdefault(why, []).append(name)
    why, names = max(reasons.items(), key=lambda item: len(item[1]))
    which = ("every object" if len(missing) == len(references)
             else f"{len(missing)} of {len(references)} objects")
    plural = "s" if len(reasons) > 2 else ""
    more = (f" ({len(reasons) - 1} other reason{plural}: matches.json's reference.reason)"
            if len(reasons) > 1 else "")
    return f"ref_cost is null for {which}: {why}{more}"


def redirection_note(redirections: list[dict]) -> str | None:
    """Under ``--placement fixed``: how many matches redirect the hand (and the largest angle), how
    many the carousel serves (None without redirection)."""
    if not redirections:
        return None
    led = [r for r in redirections if r["mode"] == "redirect"]
    carousel = len(redirections) - len(led)
    beyond = sum(r["mode"] == "carousel" and r.get("redirect_cost") is None for r in redirections)
    largest = (f" (largest angle {max(r['angle_deg'] for r in led):.2f} deg, gains "
               f"{min(r['gain'] for r in led):.3g} to "
               f"{max(r['gain'] for r in led):.3g})") if led else ""
    why = (f"{beyond} beyond the redirection budget, {carousel - beyond} cheaper there by more "
           "than the margin")
    return (f"placement fixed: {len(led)} of {len(redirections)} virtual objects stay in place, "
            f"the hand redirected{largest}; {carousel} served by the carousel ({why})")


def scan_note(props: list[tuple]) -> str | None:
    """Which props, imported from a scan, have a scale nobody measured: ``props`` [(name, scale
    verified: True, False or None for a prop not from a scan)] (None when every scan's was)."""
    unverified = [name for name, verified in props if verified is False]
    if not unverified:
        return None
    shown = ", ".join(unverified[:6]) + (f" and {len(unverified) - 6} more" if len(unverified) > 6
                                         else "")
    return (f"scale unverified for {len(unverified)} of {len(props)} props, imported from a scan "
            f"with no measurement: {shown}; a phone scan's scale is right only with a depth "
            "sensor, so every width felt on them may be off (measure a height and import again "
            "with --measured-mm, docs/scans.md)")
