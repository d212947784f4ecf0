"""Procedural indoor scenes: the scene description, rooms, furniture, materials, textures, lighting, physics, surface
samples."""
