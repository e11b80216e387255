"""The animation model: the DCT deformation field, the model update and its losses, the round plan,
rendering and playing back the animated scene.
"""
