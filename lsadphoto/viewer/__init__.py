"""The interactive luminance viewer: one self-contained HTML page per map (or pair of maps).

:func:`write_viewer` writes the page that ``lsadphoto view`` makes; :func:`viewer_fragment`
and :func:`viewer_assets` give the pieces of a page of one's own, :func:`report_viewer` the
piece the survey and comparison reports embed for each view. The
page's script and style are the package files ``viewer.js`` and ``viewer.css``; what the
page shows is computed by the package and embedded (see :mod:`lsadphoto.viewer.page`).
The user guide is ``docs/user-guide-viewer.md``.
"""

from .page import (
    GEOMETRY_STRIDE,
    PREVIEW_PIXELS,
    check_same_geometry,
    read_source_labels,
    report_viewer,
    viewer_assets,
    viewer_fragment,
    write_source_labels,
    write_viewer,
)

__all__ = ["GEOMETRY_STRIDE", "PREVIEW_PIXELS", "check_same_geometry", "read_source_labels",
           "report_viewer", "viewer_assets", "viewer_fragment", "write_source_labels", "write_viewer"]
