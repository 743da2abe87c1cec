"""Names of the RAW stage's demosaicing methods, importable without LibRaw.

The command line offers them as choices; importing :mod:`lsadphoto.raw.decode` for that
would load rawpy, tifffile and exifread in every ``lsadphoto`` process.
"""

#: Demosaic methods of :func:`lsadphoto.raw.decode.decode_raw`: ours ("superpixel") and
#: LibRaw's interpolations.
DEMOSAIC_METHODS = ("superpixel", "linear", "ahd", "dcb")

__all__ = ["DEMOSAIC_METHODS"]
