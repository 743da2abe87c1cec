"""Every metric of :func:`~lsadphoto.metrics.score.score_map`, listed once.

Each :class:`Metric` names its key (in :attr:`Score.values` and the JSON record), the public
function that computes it, its unit, a label for tables and reports, and its reference. The
scoring layer evaluates the *index* metrics by calling ``function`` with the quantities its
``inputs`` name (see :data:`QUANTITIES`) and the settings its ``options`` name, in the order
listed (an index may use one listed before it: VCP uses DGR). Field quantities come from the
one-pass :class:`~lsadphoto.metrics.field.FieldSums` (whose methods the public per-pixel
functions also use), Q from its map.

Adding a glare index is one function plus one line in :data:`INDICES`; the score record, the
CLI, the comparison of model and photo, and the uncertainties (calibration scale and pixel
noise) pick it up from here.

References
----------
The reference of each metric is in its entry; the bibliography is ``docs/bibliography.md``.
"""

from dataclasses import dataclass

from .._validation import check_choice
from .field import background_luminance, mean_luminance, vertical_illuminance
from .glare_indices import (
    cgi_Einhorn1979,
    dgi_Hopkinson1972,
    dgi_mod_Fisekis2003,
    dgp_Wienold2006,
    dgr_Guth1963,
    ugp2_Hirning2016,
    ugp_Hirning2014,
    ugr_exp_Fisekis2003,
    vcp_Guth1963,
)
from .grouping import group_sources_evalglare
from .quality import q_Budak2021
from .regions import region_statistics
from .statistics import luminance_statistics
from .ugr import ugr_CIE117, ugr_from_sum
from .veiling import veiling_luminance_CIE146, veiling_luminance_Poynter

__all__ = ["Metric", "QUANTITIES", "FIELD", "INDICES", "OTHER", "ANALYSES", "METRICS", "HEADLINE",
           "metric", "evaluate_indices"]

#: Quantities an index may take as ``inputs``: ``sources`` expands to the per-source arrays
#: (L_s [cd·m⁻²], ω_s [sr], P_s [–]); ``pixel_ugr_sum`` is ΣL²ω/P² over the source pixels
#: [cd²·m⁻⁴·sr]; the field quantities are those of :data:`FIELD`; and every index listed
#: earlier in :data:`INDICES`.
#: ``dgp_illuminance`` is the E_v DGP uses [lx]: the map's, or an external one (evalglare
#: ``-i``/``-I``).
QUANTITIES = ("sources", "pixel_ugr_sum", "vertical_illuminance", "direct_illuminance",
              "background_luminance", "mean_luminance", "dgp_illuminance")


@dataclass(frozen=True)
class Metric:
    """One metric: key, public function, unit, label, reference, and how to call it.

    Attributes
    ----------
    name : str
        Key in :attr:`Score.values` and in the JSON record.
    function : callable
        The public function computing it.
    unit : str
        Unit as printed (``"–"`` for dimensionless).
    label : str
        Short human-readable name for tables and reports.
    reference : str
        Source of the definition.
    inputs : tuple of str
        For indices: the quantities passed positionally (:data:`QUANTITIES`).
    options : tuple of (str, str)
        For indices: (keyword of ``function``, key of the score settings) pairs.
    fixed : tuple of (str, object)
        For indices: keywords with fixed values.
    digits : int
        Decimals shown in text output when no uncertainty says better.
    """

    name: str
    function: object
    unit: str
    label: str
    reference: str
    inputs: tuple = ()
    options: tuple = ()
    fixed: tuple = ()
    digits: int = 3

    def evaluate(self, quantities, settings):
        """Call :attr:`function` with the named ``quantities`` (dict) and ``settings``."""
        args = []
        for name in self.inputs:
            if name == "sources":
                args.extend(quantities["sources"])
            else:
                args.append(quantities[name])
        kwargs = {keyword: settings[key] for keyword, key in self.options}
        kwargs.update(self.fixed)
        return float(self.function(*args, **kwargs))


_SOURCES_CIE = "CIE 117:1995 eq. (1)"

#: Field quantities, from :class:`~lsadphoto.metrics.field.FieldSums`.
FIELD = (
    Metric("vertical_illuminance", vertical_illuminance, "lx", "E_v",
           "CIE 117:1995; evalglare E_v", digits=1),
    Metric("direct_illuminance", vertical_illuminance, "lx", "E_dir (glare sources)",
           "evalglare E_v_dir", digits=1),
    Metric("background_luminance", background_luminance, "cd/m²", "L_b",
           "CIE 117:1995 (E_v − E_dir)/π; evalglare -q", digits=2),
    Metric("mean_luminance", mean_luminance, "cd/m²", "mean luminance", "evalglare av_lum",
           digits=2),
)

#: Indices over glare sources, in evaluation order.
INDICES = (
    Metric("ugr_grouped", ugr_CIE117, "–", "UGR (grouped sources)", _SOURCES_CIE,
           inputs=("sources", "background_luminance"), digits=2),
    Metric("ugr_pixel", ugr_from_sum, "–", "UGR, pixel-wise",
           "Budak et al. (seed paper) §4; Scheir et al. 2015; CIE 117 eq. (1) over pixels",
           inputs=("pixel_ugr_sum", "background_luminance"), digits=2),
    Metric("dgp", dgp_Wienold2006, "–", "DGP", "Wienold & Christoffersen 2006",
           inputs=("dgp_illuminance", "sources"),
           options=(("coefficients", "dgp_coefficients"),
                    ("low_light_correction", "low_light_correction"))),
    Metric("dgp_low_light", dgp_Wienold2006, "–", "DGP with low-light correction",
           "Wienold 2009; evalglare -C", inputs=("dgp_illuminance", "sources"),
           options=(("coefficients", "dgp_coefficients"),),
           fixed=(("low_light_correction", True),)),
    Metric("dgi", dgi_Hopkinson1972, "–", "DGI", "Hopkinson 1972",
           inputs=("sources", "background_luminance"), digits=2),
    Metric("dgi_mod", dgi_mod_Fisekis2003, "–", "DGI_mod", "Fisekis et al. 2003",
           inputs=("sources", "vertical_illuminance"), digits=2),
    Metric("ugr_exp", ugr_exp_Fisekis2003, "–", "UGR_exp", "Fisekis et al. 2003",
           inputs=("sources", "vertical_illuminance", "background_luminance"), digits=2),
    Metric("ugp", ugp_Hirning2014, "–", "UGP", "Hirning et al. 2014",
           inputs=("sources", "background_luminance")),
    Metric("ugp2", ugp2_Hirning2016, "–", "UGP2", "Hirning et al. 2017",
           inputs=("sources", "background_luminance")),
    Metric("cgi", cgi_Einhorn1979, "–", "CGI", "Einhorn 1979",
           inputs=("sources", "vertical_illuminance", "direct_illuminance"), digits=2),
    Metric("dgr", dgr_Guth1963, "–", "DGR", "Guth 1963; IES Lighting Handbook",
           inputs=("sources", "mean_luminance"), digits=1),
    Metric("vcp", vcp_Guth1963, "%", "VCP", "Guth 1963; IES Lighting Handbook",
           inputs=("dgr",), options=(("constant", "vcp_constant"),), digits=1),
)

#: The lighting-quality criterion and the source counts.
OTHER = (
    Metric("q", q_Budak2021, "–", "Q", "Budak et al. (seed paper) eq. 12; FORMULAS.md §5.2"),
    Metric("n_sources", group_sources_evalglare, "", "glare sources",
           "evalglare grouping (Wienold & Christoffersen 2006)", digits=0),
    Metric("source_solid_angle", group_sources_evalglare, "sr", "source solid angle",
           "evalglare omega_sources", digits=4),
)

#: Scalars of evalglare 3.06's analyses (:mod:`~lsadphoto.metrics.analyses`), in every score.
ANALYSES = (
    Metric("veiling_luminance_poynter", veiling_luminance_Poynter, "cd/m²",
           "veiling luminance (Poynter)", "evalglare Lveil (get_disability)", digits=2),
    Metric("veiling_luminance_cie", veiling_luminance_CIE146, "cd/m²",
           "veiling luminance (CIE Stiles–Holladay)", "CIE 146:2002; evalglare Lveil_cie",
           digits=2),
    Metric("task_luminance", region_statistics, "cd/m²", "task luminance L_t",
           "evalglare -t (L_t; the mean luminance without a task)", digits=2),
    Metric("max_luminance", luminance_statistics, "cd/m²", "maximum luminance",
           "evalglare Max_Lum", digits=0),
)

#: Every metric by name, in the order of the score record.
METRICS = {m.name: m for m in FIELD + INDICES + OTHER + ANALYSES}

#: The headline metrics, in the order summaries show them: the survey's model-against-photo
#: columns (``model_<name>``) and the reports' summary tables.
HEADLINE = ("ugr_pixel", "ugr_grouped", "q", "dgp", "vertical_illuminance",
            "background_luminance", "mean_luminance")


def metric(name):
    """The :class:`Metric` called ``name``; an unknown name raises BadInputError listing all."""
    check_choice(name, "metric", tuple(METRICS))
    return METRICS[name]


def evaluate_indices(quantities, settings):
    """Every index of :data:`INDICES` from ``quantities`` (see :data:`QUANTITIES`).

    Returns a dict name → value (NaN where undefined), the field quantities included.
    """
    known = dict(quantities)
    values = {m.name: known[m.name] for m in FIELD}
    for m in INDICES:
        known[m.name] = values[m.name] = m.evaluate(known, settings)
    return values
