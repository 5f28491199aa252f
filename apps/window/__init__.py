"""What the apps' pygame windows share (the demo's, an experiment's, the on-plate calibration's guide): whether
a display is there to open one on, opening it only where a person sees it, the screen's scale when its size is
not given, and a wait for the window's next event that sleeps instead of polling."""
