"""The figure of perception's errors against ground truth (``perception_errors``): seen tracks' position error
against distance and the miss rates against bearing."""

from __future__ import annotations

from pathlib import Path

from .perception_errors import ErrorParams, Samples, summarise


def plot(s: Samples, path: Path, title: str = "") -> Path:
    """The figure: seen tracks' position error against distance (median, p90, counts) and the miss rates against
    |bearing|, binned."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = summarise(s)
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, label, colour in (("position_error_by_distance", "detected", "C0"),
                               ("remembered_error_by_distance", "not detected now (coasting, remembered)", "C1")):
        bins = [x for x in r[key] if x["n"]]
        mid = [0.5 * (x["lo"] + (x["hi"] if x["hi"] is not None else x["lo"] + 2.0)) for x in bins]
        a.plot(mid, [x["median"] for x in bins], "o-", color=colour, label=f"{label}: median")
        a.plot(mid, [x["p90"] for x in bins], "v--", color=colour, alpha=0.6, label=f"{label}: p90")
        for xm, x in zip(mid, bins, strict=True):
            a.annotate(str(x["n"]), (xm, x["p90"]), textcoords="offset points", xytext=(0, 4), ha="center",
                       fontsize=7, color=colour)
    a.set_xlabel("true distance from the robot (m)")
    a.set_ylabel("position error (m)")
    a.set_title("member position error (counts: member-ticks)")
    a.legend(fontsize=7, loc="upper left")
    a.grid(alpha=0.3)
    bins = [x for x in r["by_bearing"] if x["n"]]
    mid = [0.5 * (x["lo"] + x["hi"]) for x in bins]
    b.plot(mid, [x["missed_rate"] for x in bins], "o-", label="missed (no track)")
    b.plot(mid, [x["unseen_rate"] for x in bins], "s--", label="not detected this frame")
    for xm, x in zip(mid, bins, strict=True):
        b.annotate(str(x["n"]), (xm, x["unseen_rate"]), textcoords="offset points", xytext=(0, 4), ha="center",
                   fontsize=7)
    b.axvline(0.5 * ErrorParams().hfov_deg, color="grey", ls=":", label="half the camera's FOV")
    b.set_xlabel("|true bearing| from the robot (deg)")
    b.set_ylabel("rate")
    b.set_ylim(-0.02, 1.05)
    b.set_title("members missed against bearing")
    b.legend(fontsize=7)
    b.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
