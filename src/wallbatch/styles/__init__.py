"""Wall potential styles: one registry entry (`WallStyle`) per style and the registry `STYLES`.

May import: numpy, wallbatch.geometry and the leaves (units, expr).
"""

from __future__ import annotations

from wallbatch.styles.base import Param, WallStyle
from wallbatch.styles.ees import EES
from wallbatch.styles.flat import STYLES as FLAT_STYLES
from wallbatch.styles.lepton import LEPTON
from wallbatch.styles.table import TABLE

# every wall style with per-face parameters, in a fixed order (the compiled dispatch numbers them);
# a new style is one entry here (the config models, fix lines and kernels are built from this at import)
STYLES: dict[str, WallStyle] = {**FLAT_STYLES, EES.name: EES, LEPTON.name: LEPTON, TABLE.name: TABLE}


def region_styles() -> tuple[str, ...]:
    """Styles usable as the potential of wall/region."""
    return tuple(n for n, s in STYLES.items() if s.region)


__all__ = ["STYLES", "FLAT_STYLES", "Param", "WallStyle", "region_styles"]
