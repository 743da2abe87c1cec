"""Lighting-quality metrics of absolute luminance maps.

The public API, imported on first use (so that ``import lsadphoto.metrics`` stays cheap):
:func:`score_map` and :class:`Score`; the metric registry (:data:`METRICS`, :func:`metric`);
the field integrals, glare-source rules and grouping; UGR and the other glare indices; the
Q criterion and luminance statistics.
"""

import importlib

#: Public name → module that defines it.
_EXPORTS = {
    "score_map": "score", "Score": "score", "ScoredSource": "score",
    "METRICS": "registry", "Metric": "registry", "metric": "registry",
    "FieldSums": "field", "field_sums": "field", "vertical_illuminance": "field",
    "mean_luminance": "field", "background_luminance": "field", "evaluated_field": "field",
    "select_source_pixels": "sources", "task_luminance": "sources",
    "group_sources_evalglare": "grouping", "position_pixel_evalglare": "grouping",
    "GlareSource": "grouping",
    "ugr_CIE117": "ugr", "ugr_pixel": "ugr", "ugr_sum": "ugr", "ugr_from_sum": "ugr",
    "dgp_Wienold2006": "glare_indices", "dgi_Hopkinson1972": "glare_indices",
    "dgi_mod_Fisekis2003": "glare_indices", "ugr_exp_Fisekis2003": "glare_indices",
    "ugp_Hirning2014": "glare_indices", "ugp2_Hirning2016": "glare_indices",
    "dgr_Guth1963": "glare_indices", "vcp_Guth1963": "glare_indices",
    "cgi_Einhorn1979": "glare_indices",
    "q_Budak2021": "quality", "q_sweep": "quality",
    "luminance_statistics": "statistics",
    "dgp_coefficients": "glare_indices",
    # evalglare 3.06's analyses
    "region_statistics": "regions", "band_region": "regions", "zone_map": "regions",
    "zone_statistics": "regions", "mask_region": "regions", "split_sources_at_zones": "regions",
    "pgsv_Tokura1996": "regions", "pgsv_saturation": "regions", "pgsv_evalglare": "regions",
    "veiling_luminance_Poynter": "veiling", "veiling_luminance_CIE146": "veiling",
    "age_factor_CIE146": "veiling",
    "source_columns": "contributions", "source_illuminance": "contributions",
    "fill_rows_evalglare": "corrections", "low_light_correction_on": "corrections",
    "regroup_sources": "grouping_options", "smoothing_labels": "grouping_options",
    "patch_labels": "grouping_options",
    "check_picture": "checkfile", "write_checkfile": "checkfile",
    "evalglare_analyses": "analyses",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
