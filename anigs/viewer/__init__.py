"""Interactive WebGL2 viewer of the animated scene and its compact animated format.

* :mod:`anigs.viewer.compact`: the compact file (canonical Gaussians once, DCT motion only
  for the dynamic ones), writer and exact loader;
* :mod:`anigs.viewer.build`: ``build_viewer`` writes a self-contained viewer folder;
* :mod:`anigs.viewer.serve`: serve a folder on 127.0.0.1;
* :mod:`anigs.viewer.cli`: the ``anigs view`` subcommand.
"""
from anigs.viewer.compact import (CompactFormatError, CompactScene, decode_compact, encode_compact, load_compact,
                                  save_compact, write_frame_plys)

__all__ = ["CompactFormatError", "CompactScene", "decode_compact", "encode_compact", "load_compact",
           "save_compact", "write_frame_plys"]
