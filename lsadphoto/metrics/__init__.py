"""Lighting-quality metrics of absolute luminance maps.

The public API, imported on first use (:mod:`lsadphoto._lazy`, so that ``import
lsadphoto.metrics`` stays cheap): :func:`score_map` and :class:`Score`; the metric registry
(:data:`METRICS`, :func:`metric`); the field integrals, glare-source rules and grouping; UGR
and the other glare indices; the Q criterion and luminance statistics.
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".score": ["score_map", "Score", "ScoredSource"],
    ".registry": ["METRICS", "Metric", "metric"],
    ".field": ["FieldSums", "field_sums", "vertical_illuminance", "mean_luminance",
               "background_luminance", "evaluated_field"],
    ".sources": ["select_source_pixels", "task_luminance"],
    ".grouping": ["group_sources_evalglare", "position_pixel_evalglare", "GlareSource"],
    ".ugr": ["ugr_CIE117", "ugr_pixel", "ugr_sum", "ugr_from_sum"],
    ".glare_indices": ["dgp_Wienold2006", "dgi_Hopkinson1972", "dgi_mod_Fisekis2003",
                       "ugr_exp_Fisekis2003", "ugp_Hirning2014", "ugp2_Hirning2016",
                       "dgr_Guth1963", "vcp_Guth1963", "cgi_Einhorn1979", "dgp_coefficients"],
    ".quality": ["q_Budak2021", "q_sweep"],
    ".statistics": ["luminance_statistics"],
    ".regions": ["region_statistics", "band_region", "zone_map", "zone_statistics", "mask_region",
                 "split_sources_at_zones", "pgsv_Tokura1996", "pgsv_saturation", "pgsv_evalglare"],
    ".veiling": ["veiling_luminance_Poynter", "veiling_luminance_CIE146", "age_factor_CIE146"],
    ".contributions": ["source_columns", "source_illuminance"],
    ".corrections": ["fill_rows_evalglare", "low_light_correction_on"],
    ".grouping_options": ["regroup_sources", "smoothing_labels", "patch_labels"],
    ".checkfile": ["check_picture", "write_checkfile"],
    ".analyses": ["evalglare_analyses"],
})
