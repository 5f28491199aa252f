"""ultraglide: tactile texture rendering for ultrasonic friction displays.

The packages ``ultraglide.textures``, ``ultraglide.render``, ``ultraglide.devices`` and
``ultraglide.apps`` live in the repository's top-level folders of the same names (setuptools'
package-dir mapping in pyproject.toml).
"""

__version__ = "0.2.0"
