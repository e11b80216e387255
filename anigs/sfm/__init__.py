"""Structure from motion: COLMAP via pycolmap, its config, model conversion, bundle adjustment, alignment."""
