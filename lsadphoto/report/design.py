"""The HTML report of a design search: the Pareto front and the best design's maps and grids.

Formatting only: every number comes from the ``design.json`` record that
:func:`lsadphoto.design.run.run_design` writes; the pictures from the best design's maps.
"""

import tempfile
from pathlib import Path

from .html import _document, _figure_html, _section, _table, _tag


def _fmt(value, digits=4):
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _pareto_png(record):
    """PNG bytes of the Pareto front over the first two objectives (or objective vs design)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from .plots import png_bytes

    objectives = record["objectives"]
    front = record["pareto"]
    fig = Figure(figsize=(6.0, 4.0), dpi=100)
    ax = fig.subplots()

    def values(rec, k):
        v = rec["objectives"][k]
        return None if v is None else (v if objectives[k]["sense"] == "min" else -v)

    label = [f"{o['metric']} ({o['sense']}, {o.get('grid') or o.get('view')})" for o in objectives]
    if len(objectives) >= 2:
        xs = [values(r, 0) for r in front]
        ys = [values(r, 1) for r in front]
        ax.plot(xs, ys, "o", color="tab:blue", label="Pareto set")
        if record.get("best"):
            ax.plot([values(record["best"], 0)], [values(record["best"], 1)], "*", ms=14,
                    color="tab:red", label="best")
        ax.set_xlabel(label[0])
        ax.set_ylabel(label[1])
    else:
        ax.plot(range(len(front)), [values(r, 0) for r in front], "o")
        ax.set_xlabel("Pareto design")
        ax.set_ylabel(label[0])
    ax.legend(loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return png_bytes(fig)


def _map_pngs(name, lmap):
    from ..io import write_false_colour_png
    from ..metrics import score_map
    from .figures import write_glare_source_png

    with tempfile.TemporaryDirectory() as tmp:
        fc, gs = Path(tmp) / "fc.png", Path(tmp) / "gs.png"
        write_false_colour_png(lmap, fc, title=f"{name}: luminance [cd/m²]")
        score = score_map(lmap, noise_samples=0, q_noise_samples=0)
        write_glare_source_png(lmap.luminance, score.source_labels, gs, title=f"{name}: glare sources")
        return fc.read_bytes(), gs.read_bytes()


def design_report_html(record, best_maps):
    """The report as one self-contained HTML text (images embedded as data URIs)."""
    sections = []
    nav = [("summary", "Summary"), ("pareto", "Pareto set"), ("best", "Best design")]
    rows = [["designs in the space", _fmt(record["design_count"])],
            ["search", record["method"]], ["designs evaluated", _fmt(record["evaluations"])],
            ["evaluations per second", _fmt(record["evaluations_per_second"], 3)]]
    rows += [[f"objective {k + 1}", f"{o['sense']} {o['metric']} ({o.get('grid') or o.get('view')})"]
             for k, o in enumerate(record["objectives"])]
    rows += [["constraint", f"{c['metric']} ({c.get('grid') or c.get('view')}) "
                            f"{'≥ ' + _fmt(c['min']) if c.get('min') is not None else ''} "
                            f"{'≤ ' + _fmt(c['max']) if c.get('max') is not None else ''}"]
             for c in record["constraints"]]
    notes = [_tag("p", n, cls="note") for n in record.get("notes", [])]
    sections.append(_section("summary", "Summary", _table(["", ""], rows), *notes))
    head = ["design", "luminaires", "power [W]"] + [o["metric"] for o in record["objectives"]]
    table_rows = []
    for k, r in enumerate(record["pareto"]):
        shown = [v if o["sense"] == "min" or v is None else -v
                 for v, o in zip(r["objectives"], record["objectives"])]
        table_rows.append([str(k + 1), _fmt(r["luminaires"]), _fmt(r["power_w"])] + [_fmt(v) for v in shown])
    pareto = [_table(head, table_rows, numeric=range(1, len(head)))]
    if record["pareto"]:
        pareto.insert(0, _figure_html(_pareto_png(record), "Pareto front of the feasible designs"))
    sections.append(_section("pareto", "Pareto set", *pareto))
    best = record.get("best")
    if best is None:
        rows = [[str(k + 1), "; ".join(v[0] for v in r["violations"])] for k, r in enumerate(record["closest"])]
        sections.append(_section("best", "Best design", _tag("p", "No design meets the constraints. "
                                                              "The closest designs violate:"),
                                 _table(["design", "violations"], rows)))
    else:
        parts = []
        lums = [[str(i), c["type"], _fmt(c["level"])] for i, c in enumerate(best["choices"]) if c]
        parts.append(_table(["position", "type", "level"], lums))
        view_rows = []
        for name, v in best["views"].items():
            u = v["uncertainty"]
            view_rows.append([name] + [f"{_fmt(v[k])} ± {_fmt(u.get(k), 2)}"
                                       for k in ("q", "ugr_pixel", "ugr_grouped", "dgp", "E_v")])
        parts.append(_table(["view", "Q", "UGR (pixel)", "UGR (grouped)", "DGP", "E_v [lx]"], view_rows))
        grid_rows = [[name, f"{_fmt(g['e_m'])} ± {_fmt(g['e_m_standard_error'], 2)}", _fmt(g["e_min"]),
                      _fmt(g["u0"], 3)] for name, g in best["grids"].items()]
        if grid_rows:
            parts.append(_table(["grid", "Ē [lx]", "E_min [lx]", "U₀"], grid_rows))
        for name, lmap in best_maps.items():
            fc, gs = _map_pngs(name, lmap)
            parts.append(_figure_html(fc, f"{name}: false-colour luminance of the best design"))
            parts.append(_figure_html(gs, f"{name}: glare sources of the best design"))
        sections.append(_section("best", "Best design", *parts))
    return _document(f"Design: {record['name']}", f"{record['problem']}", sections, nav)
