"""Structure from motion: COLMAP via pycolmap (colmap), its config, model conversion (model), the
refinement bundle adjustment (bundle) and the similarity alignment to ground truth or z-up (align).
"""
