"""On-plate calibration: the plan of amplitude steps at several presses, its recording from the plate's sensors,
and the participant's guide on the screen (``ultraglide calibrate --device URL``)."""
