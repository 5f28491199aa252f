"""Haptic content in the formats the field uses, read and written by typed loaders at the edge.

- :mod:`.gltf`: glTF 2.0 scenes with ``MPEG_haptic_material`` friction textures, in and out;
- :mod:`.mapping`: how a texel becomes a friction ratio, stated in one place;
- :mod:`.timeline` and the effect readers (:mod:`.ahap`, :mod:`.meta_haptic`, :mod:`.hjif`): designers' effects
  as ultraglide temporal effects, with what a friction display cannot render said;
- :mod:`.haps`: Interhaptics ``.haps`` files: the texture block as a grating, the vibration block as effects;
- :mod:`.hjif`: MPEG-I haptics (ISO/IEC 23090-31) ``.hjif`` files written from a rendered stroke.

docs/formats.md tells what maps to what and what is lost. This package imports nothing of ours outside
``ultraglide.textures`` but the shared safe readers and writers (:mod:`ultraglide.inputs`,
:mod:`ultraglide.atomic`), as the rest of ``textures`` does.
"""
