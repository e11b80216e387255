"""Splat file formats of other tools, read and written without their code.

- :mod:`~anigs.formats.orientation`: the frames other tools show anigs's +z-up scene in;
- :mod:`~anigs.formats.compressed_ply`: SuperSplat's / splat-transform's "compressed PLY" (reader);
- :mod:`~anigs.formats.spz`: Niantic's SPZ (writer and reader, version 3);
- :mod:`~anigs.formats.gltf`: glTF binary with ``KHR_gaussian_splatting`` (writer);
- :mod:`~anigs.formats.splats`: any of the PLY forms, with the quantisation step of each position.
"""
