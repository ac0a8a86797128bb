"""DanceNet for Blender: music-driven dance generation (Zhuang et al., 2020). Never imports bpy."""

__version__ = "0.1.0"
