"""Splat file formats of other tools, read and written without their code.

- :mod:`~anigs.formats.orientation`: the frames other tools show anigs's +z-up scene in;
- :mod:`~anigs.formats.compressed_ply`: SuperSplat's / splat-transform's "compressed PLY" (reader);
- :mod:`~anigs.formats.spz`: Niantic's SPZ (writer of version 3, reader of versions 2 to 4; version 4
  needs the optional ``zstandard`` module);
- :mod:`~anigs.formats.gltf`: glTF binary with ``KHR_gaussian_splatting`` (writer and reader);
- :mod:`~anigs.formats.splats`: any of the PLY forms, with the quantisation step of each position,
  antimatter15's ``.splat``, and :func:`~anigs.formats.splats.read_splat_file`, one entry for every
  format above.
"""
