"""Physical constants, instrument defaults and the numeric policy, with their sources.

References
----------
- CIE 018:2019, *The Basis of Physical Photometry*: K_m = 683 lm/W.
- Radiance ``src/common/color.h``: ``WHTEFFICACY`` = 179 lm/W and the luminance weights of
  Radiance RGB primaries (FORMULAS.md §2.4.1).
- Konica Minolta LS-100 datasheet: 1° acceptance angle, accuracy ±2 % of reading
  (illuminant A).
- ISO 2720:1974 reflected-light meter calibration constant K = 12.5 cd·s·m⁻² (quoted for
  comparison with the camera calibration constant; not used as a default).
"""

import numpy as np

#: Maximum luminous efficacy of photopic vision [lm·W⁻¹] (CIE 018:2019).
K_M = 683.0

#: Luminous efficacy Radiance assumes for its RGB "radiance" values [lm·W⁻¹]
#: (Radiance ``WHTEFFICACY``; FORMULAS.md §2.4.1).
RADIANCE_WHITE_EFFICACY = 179.0

#: Weights turning Radiance RGB into luminance before the efficacy factor
#: (Radiance ``color.h`` ``CIE_rf, CIE_gf, CIE_bf``).
RADIANCE_RGB_LUMINANCE_WEIGHTS = (0.265074, 0.670115, 0.064811)

#: Acceptance angle of a Konica Minolta LS-100 spot luminance meter [rad] (full cone angle, 1°).
LS100_ACCEPTANCE_ANGLE = np.deg2rad(1.0)

#: LS-100 stated accuracy: ±2 % of reading; read as the bounds of a rectangular
#: distribution, its relative standard uncertainty is 0.02/√3 (GUM §4.3.7).
LS100_RELATIVE_STANDARD_UNCERTAINTY = 0.02 / np.sqrt(3.0)

#: Coefficient of variation inside a spot cone above which the spot is reported non-uniform.
SPOT_CV_WARNING = 0.10

#: Fraction of the black-to-white range above which a raw value counts as saturated.
#: Sensors leave their linear range a little before the nominal white level.
SATURATION_FRACTION = 0.98

#: Default relative standard uncertainty of a camera calibration constant that a profile
#: gives without one (exposure-equation estimates without a spot reading). HDR photometry
#: reaches about ±10 % (Budak & Ilyina 2023; Inanici 2006).
DEFAULT_CALIBRATION_CONSTANT_UNCERTAINTY = 0.10

#: Storage and accumulation types (DESIGN.md conventions).
STORAGE_DTYPE = np.float32
ACCUMULATION_DTYPE = np.float64
