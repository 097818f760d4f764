"""ssbl-pb: Staged Social Behavior Learning (Gao et al., RO-MAN 2019) for Pepper in PyBullet."""

__version__ = "0.1.0"
