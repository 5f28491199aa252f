"""The friction estimator: from the plate's sensors, the finger's friction while it slides, and the model adapted to it.

It takes SENSORS samples (vibration amplitude µm p-p, normal and lateral force N, at the device's sensor
rate) and keeps:

* **sliding or not**: a finger whose normal force is below ``min_force_n`` has lifted; one the touch panel
  says stands still (below ``min_speed_mm_s``), or whose lateral force is far below any friction the model
  allows (a finger at rest sticks: its lateral force is not friction), rests. Only sliding samples are
  used; a finger at rest gives no friction estimate.
* **mu and mu0**: mu = lateral / normal force, sample by sample. mu0, the friction without vibration, comes
  from the **adapted model's extrapolation to zero amplitude**: it is the first parameter of the online fit
  below, so moments at zero amplitude pin it directly when they occur, and the curve through the other
  amplitudes does in between. The measured ratio is mu / mu0.
* **the adaptive model**: the host's friction model ``r(a, F)`` with its amplitude axis scaled by ``k``:
  ``mu = mu0 r(a / k, F)``. ``ln mu0`` and ``ln k`` are fitted by recursive least squares, linearised at the
  present estimates (the slope in ``ln k`` from the model itself, by central differences, so any model works:
  the stretched law, a table, a calibration), each parameter a random walk of its own (a Kalman filter): the
  covariance grows each sample by ``diag(q0, q1)``, set from the memories ``mu0_memory_s`` (1 s) and
  ``scale_memory_s`` (0.1 s). Samples are weighted by the force (the noise of mu goes as 1/F), and the
  covariance is bounded so that a stretch without excitation (a steady amplitude) does not wind it up.

  Why two memories: where the amplitude never leaves a narrow band, the samples fix only the product
  ``mu0 r(a / k)``, not mu0 and k apart (a plan that holds a lagging finger's friction steady, issue 43: the
  two regressors correlated 0.8-0.99 over half a second). The friction at rest changes slowly (moisture, over
  tens of seconds); the scale takes what the press changes within a second (a force law unlike the model's).
  With one forgetting factor for both, the covariance grew along the product's valley and any change the model
  could not explain moved the estimate along it: mu0 fell, the ratio measured as mu / mu0 rose, the loop drove
  more vibration, the finger's friction fell with it, and the samples agreed again, until k reached its bound
  of 4. With k's variance growing a hundred times faster than mu0's, what the samples cannot place goes to k.

The force sensors are slower than the amplitude sensor: the predicted ratio is passed through a model of
them (a first-order low-pass and a delay, a fraction of a sample allowed) before it is compared with the
measured one, so an amplitude that changes at 200 Hz is still fitted without lag. The host starts from the
nominal ``sensor_bandwidth_hz`` and ``sensor_delay_s`` and identifies the real ones from the data
(:class:`SensorTiming`); until it has, while the ratio moves, nothing is fitted (a fit through the wrong
timing chases a lagging signal: with sensors at 150 Hz and 3 ms where 300 Hz and 1 ms were assumed, the
scale ran to 1.5 times its truth before this identification).

NaN, values out of any physical range, and a finger's forces the sensors cannot give raise a *fault*: the
estimate says which, and the loop falls back to open loop (:mod:`render.engine.friction_controller`).
Pure: no threads, no clocks but the sample count; :meth:`FrictionEstimator.update` for each batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from ultraglide.devices.output.kernels import first_order_filter
from ultraglide.render.physics.errors import ModelError

MAX_FORCE_N = 20.0  # a reading beyond this is not a fingertip: a sensor fault
MIN_NORMAL_N = -0.2  # a normal force this negative is a sensor fault (offset drift, a broken wire)
DIFFERENCE_STEP = 0.02  # ln k step of the central difference for the model's slope
LN_K_RANGE = (math.log(0.25), math.log(4.0))  # the adapted scale stays within 1/4 to 4 x the model's
LN_MU0_RANGE = (math.log(0.02), math.log(5.0))
REGRESSOR = 0.7  # a typical regressor (mu at 0.5 N): the memories' nominal scale
MAX_COVARIANCE = 0.5  # bound on the trace of P (ln units²): no wind-up without excitation
INITIAL_COVARIANCE = np.diag([0.05, 0.05])


@dataclass(frozen=True)
class EstimatorSettings:
    """What the estimator assumes. Times s, frequencies Hz, forces N, speeds mm/s.

    ``sensor_delay_s`` and ``sensor_bandwidth_hz``: the host's model of the force sensors (the simulated plate's
    defaults: 1 ms, 300 Hz); ``mu0_memory_s`` and ``scale_memory_s``: the adaptive model's memories of mu0 and of
    the scale (nominal: a random walk's, at a regressor of 0.7); ``min_force_n``: lighter is lifted;
    ``min_speed_mm_s``: slower (as the touch panel says) is at rest; ``resting_fraction``: a lateral force below
    this share of the friction the adapted model predicts is a finger at rest; ``prior_mu0``: mu0 before any
    measurement; ``confirm_s``: sliding must last this long before its estimates are trusted.

    Examples
    --------
    >>> settings = EstimatorSettings()
    >>> settings.sensor_delay_s, settings.sensor_bandwidth_hz, settings.min_speed_mm_s
    (0.001, 300.0, 5.0)
    """

    sensor_delay_s: float = 0.001
    sensor_bandwidth_hz: float = 300.0
    mu0_memory_s: float = 1.0
    scale_memory_s: float = 0.1
    min_force_n: float = 0.05
    min_speed_mm_s: float = 5.0
    resting_fraction: float = 0.25
    prior_mu0: float = 1.0
    confirm_s: float = 0.03
    reference_force_n: float = 0.5
    identify_sensors: bool = True

    def __post_init__(self) -> None:
        for name, low, high in (("sensor_delay_s", 0.0, 0.1), ("sensor_bandwidth_hz", 0.0, 20000.0),
                                ("mu0_memory_s", 0.01, 600.0), ("scale_memory_s", 0.01, 600.0),
                                ("min_force_n", 0.0, 5.0),
                                ("min_speed_mm_s", 0.0, 1000.0), ("resting_fraction", 0.0, 1.0),
                                ("prior_mu0", 0.02, 5.0), ("confirm_s", 0.0, 5.0), ("reference_force_n", 0.01, 10.0)):
            value = getattr(self, name)
            if not (math.isfinite(value) and low <= value <= high):
                raise ValueError(f"the friction estimator's {name} must lie in {low:g}..{high:g}, got {value}")


@dataclass(frozen=True)
class FrictionEstimate:
    """The estimator's view after a batch. ``state``: ``waiting`` (no sliding yet), ``sliding``, ``resting``,
    ``lifted`` or ``fault``; ``reason`` says why in words. ``scale`` is k (the model's amplitude axis is
    stretched by it), ``mu0`` the friction without vibration, ``force_n`` the normal force (smoothed),
    ``measured_ratio`` mu / mu0 over the batch (NaN while not sliding).

    Examples
    --------
    >>> estimate = FrictionEstimate()
    >>> estimate.state, estimate.reason, estimate.sliding
    ('waiting', 'no sensor samples yet', False)
    """

    state: str = "waiting"
    reason: str = "no sensor samples yet"
    mu0: float = 1.0
    scale: float = 1.0
    force_n: float = math.nan
    measured_ratio: float = math.nan
    sliding_samples: int = 0  # used for the fit since the start
    sensor_sample: int = -1  # the newest sample's number (the device's count)

    @property
    def sliding(self) -> bool:
        """Whether the finger slid over the batch (the state is ``sliding``).

        Examples
        --------
        >>> FrictionEstimate("sliding", "the finger slides").sliding, FrictionEstimate("resting", "no motion").sliding
        (True, False)
        """
        return self.state == "sliding"


@dataclass
class BatchResult:
    """Per sample of the batch (arrays of its length): what the controller's correction needs.

    Examples
    --------
    A batch of 400 sliding samples (0.4 s at 1 kHz), every one of them used:

    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> model = StretchedExponentialModel()
    >>> amplitude, force = np.tile(np.linspace(0.0, 5.0, 100), 4), np.full(400, 0.5)
    >>> result = FrictionEstimator(model).update(0, amplitude, force, model.relative_friction(amplitude, 0.5) * force,
    ...                                          panel_speed_mm_s=100.0)
    >>> isinstance(result, BatchResult), result.measured_ratio.shape, int(result.used.sum())
    (True, (400,), 400)
    """

    measured_ratio: np.ndarray  # mu / mu0 (NaN where not used)
    intended_ratio: np.ndarray  # what the controller meant at the amplitude the plate reached: r(a / (k (1 + g)))
    sensitivity: np.ndarray  # d(ratio)/d(ln amplitude) at that sample, as the sensors see it (<= 0)
    used: np.ndarray  # the sample was a sliding finger's, trusted
    estimate: FrictionEstimate = field(default_factory=FrictionEstimate)


def nan_mean(values: np.ndarray) -> float:
    """``np.nanmean``'s value (the same sum of the same numbers, over the same count) without its wrappers, a few
    µs a call on the short batches here; NaN when every value is.

    Parameters
    ----------
    values : numpy.ndarray

    Returns
    -------
    float

    Examples
    --------
    >>> nan_mean(np.array([1.0, np.nan, 3.0])), nan_mean(np.array([np.nan]))
    (2.0, nan)
    """
    missing = np.isnan(values)
    count = values.size - int(np.count_nonzero(missing))
    return float(np.add.reduce(np.where(missing, 0.0, values), axis=None)) / count if count else math.nan


def mean(values: np.ndarray) -> float:
    """``np.mean``'s value for a float array (its sum over its count) without its wrapper.

    Parameters
    ----------
    values : numpy.ndarray

    Returns
    -------
    float

    Examples
    --------
    >>> mean(np.array([1.0, 2.0]))
    1.5
    """
    return float(np.add.reduce(values, axis=None)) / values.size


def median(values) -> float:
    """``np.median``'s value for a short batch of finite numbers (the middle one, or the mean of the middle two).

    Parameters
    ----------
    values : numpy.ndarray

    Returns
    -------
    float

    Examples
    --------
    >>> median(np.array([3.0, 1.0, 2.0])), median(np.array([4.0, 1.0, 2.0, 3.0]))
    (2.0, 2.5)
    """
    ordered = sorted(values.tolist())
    half = len(ordered) // 2
    return ordered[half] if len(ordered) % 2 else (ordered[half - 1] + ordered[half]) / 2.0


def lowpass_coefficients(bandwidth_hz: float, rate_hz: float) -> tuple[np.ndarray, np.ndarray] | None:
    """A first-order low-pass at ``bandwidth_hz`` discretised by the bilinear transform (whose delay at low
    frequencies is the continuous filter's, 1 / (2 pi f) s); None for no filter.

    Parameters
    ----------
    bandwidth_hz : float
        The corner (Hz); 0 or less: no filter.
    rate_hz : float
        The sample rate (Hz).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray) or None
        b and a, as ``scipy.signal.lfilter`` takes them.

    Examples
    --------
    >>> b, a = lowpass_coefficients(100.0, 1000.0)
    >>> round(float(b.sum() / a.sum()), 12)                              # unity gain at 0 Hz
    1.0
    >>> lowpass_coefficients(0.0, 1000.0) is None
    True
    """
    if not bandwidth_hz > 0:
        return None
    corner = 2.0 * math.pi * bandwidth_hz
    twice = 2.0 * rate_hz
    gain = corner / (twice + corner)
    return np.array([gain, gain]), np.array([1.0, -(twice - corner) / (twice + corner)])


def fractional_delay(delay_samples: float) -> tuple[int, np.ndarray]:
    """A delay of ``delay_samples`` (>= 0) as an FIR: its first tap's offset and its taps (a whole number of
    samples: one tap; else the four-tap Lagrange interpolator around it, flat to 2 % up to a fifth of the rate).

    Parameters
    ----------
    delay_samples : float
        The delay (samples), >= 0.

    Returns
    -------
    (int, numpy.ndarray)
        The first tap's offset (samples) and the taps (they sum to 1).

    Examples
    --------
    >>> fractional_delay(2.0)
    (2, array([1.]))
    >>> first, taps = fractional_delay(2.5)                                # Lagrange around 2.5
    >>> first, taps.tolist(), float(taps.sum())
    (1, [-0.0625, 0.5625, 0.5625, -0.0625], 1.0)
    """
    whole = math.floor(delay_samples)
    fraction = delay_samples - whole
    if fraction < 1e-6:
        return whole, np.ones(1)
    first = max(whole - 1, 0)
    at = delay_samples - first  # within the four taps
    taps = np.array([math.prod((at - m) / (k - m) for m in range(4) if m != k) for k in range(4)])
    return first, taps


class SensorModel:
    """The host's model of the force sensors at the sensor rate: a first-order low-pass then a delay (a
    fraction of a sample allowed), applied to several channels at once, its state kept between batches;
    :meth:`set` changes both (the identification below retunes it).

    Examples
    --------
    A 2 ms delay at 1 kHz (no low-pass) shifts by two samples; a 100 Hz low-pass rises towards a step:

    >>> import numpy as np
    >>> SensorModel(1, 1000.0, 0.0, 0.002)(np.array([[1.0, 2.0, 3.0, 4.0]])).tolist()
    [[0.0, 0.0, 1.0, 2.0]]
    >>> rising = SensorModel(1, 1000.0, 100.0, 0.0)(np.ones((1, 4)))[0]
    >>> bool(np.all(np.diff(rising) > 0) and rising[-1] < 1.0)
    True
    """

    MAX_DELAY = 64  # samples

    def __init__(self, channels: int, rate_hz: float, bandwidth_hz: float, delay_s: float):
        self.channels = channels
        self.rate_hz = float(rate_hz)
        self._history = np.zeros((channels, self.MAX_DELAY + 4))  # filtered samples, newest last
        self._zi = None
        self.set(bandwidth_hz, delay_s)
        self.reset(None)

    def __repr__(self) -> str:
        return f"SensorModel({self.bandwidth_hz:g} Hz, {1000 * self.delay_s:.2f} ms)"

    def set(self, bandwidth_hz: float, delay_s: float) -> None:
        """Retune the sensors' model: a first-order low-pass at ``bandwidth_hz`` (Hz) then ``delay_s`` (s, held within
        the delay line); a filter made where there was none starts settled on the newest filtered value.

        Parameters
        ----------
        bandwidth_hz : float
            Hz (0: no filter).
        delay_s : float
            s.

        Examples
        --------
        Without a filter, a delay of 3 samples at 1 kHz (the history settled on 1):

        >>> import numpy as np
        >>> sensors = SensorModel(1, 1000.0, 0.0, 0.0)
        >>> sensors.set(0.0, 0.003)
        >>> sensors.reset(np.array([1.0]))
        >>> sensors(np.array([[5.0, 6.0, 7.0, 8.0]])).tolist()
        [[1.0, 1.0, 1.0, 5.0]]
        """
        self.bandwidth_hz = float(bandwidth_hz)
        self.delay_s = min(max(float(delay_s), 0.0), (self.MAX_DELAY - 2) / self.rate_hz)
        coefficients = lowpass_coefficients(bandwidth_hz, self.rate_hz)
        had = self.b if hasattr(self, "b") else None
        self.b, self.a = coefficients if coefficients is not None else (None, None)
        if self.b is None:
            self._zi = None
        elif had is None or self._zi is None:  # settle on the newest filtered value
            self._zi = ((self.b[1] - self.a[1]) * self._history[:, -1])[:, None]
        self._first, self._taps = fractional_delay(self.delay_s * self.rate_hz)

    def reset(self, first: np.ndarray | None) -> None:
        """Start over (the first batch, or after a gap): settled on ``first`` (one value a channel).

        Parameters
        ----------
        first : numpy.ndarray or None
            One value a channel (None: zeros).

        Examples
        --------
        Settled on 2, a constant 2 passes through the filter unchanged:

        >>> import numpy as np
        >>> sensors = SensorModel(1, 1000.0, 100.0, 0.0)
        >>> sensors.reset(np.array([2.0]))
        >>> sensors(np.full((1, 3), 2.0)).round(9).tolist()
        [[2.0, 2.0, 2.0]]
        """
        start = np.zeros(self.channels) if first is None else np.asarray(first, dtype=float)
        # settled, in the transposed form y = b0 x + z, z = b1 x - a1 y: z = (b1 - a1) x at rest
        self._zi = None if self.b is None else ((self.b[1] - self.a[1]) * start)[:, None]
        self._history[:] = start[:, None]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``x``: channels × samples; the filtered and delayed signal of the same shape."""
        n = x.shape[1]
        if self.b is not None:
            x, self._zi = first_order_filter(self.b, self.a, x, zi=self._zi)
        kept = self._history.shape[1]
        joined = np.concatenate((self._history, x), axis=1)
        out = np.zeros((self.channels, n))
        for k, tap in enumerate(self._taps.tolist()):
            lag = self._first + k
            out += tap * joined[:, kept - lag:kept - lag + n]
        self._history = joined[:, -kept:]
        return out


class SensorTiming:
    """The force sensors' bandwidth and delay, identified from the data (a sensor slower or later than the host
    assumes would make the fit chase a lagging signal).

    It keeps the last ``BUFFER`` samples of the model's ratio at the measured amplitude (before any sensor
    model) and of the measured mu, and every ``EVERY`` samples, if enough of them slid and the ratio moved,
    tries bandwidths from a third to three times the nominal and every delay up to ``MAX_LAG`` samples: the
    pair whose filtered, delayed ratio best explains mu (least squares with an intercept, so mu0 and the
    scale do not matter) wins, its delay refined to a fraction of a sample by a parabola.

    Examples
    --------
    Nothing is identified before enough samples slid:

    >>> import numpy as np
    >>> timing = SensorTiming(1000.0, 300.0, 0.001)
    >>> timing.add(np.ones(10), np.ones(10)), timing.found, timing.nominal_lag
    (None, None, 1.0)
    """

    BUFFER = 1024
    EVERY = 500
    FIRST = 300  # samples before the first search
    FIRST_EVERY = 100
    MAX_LAG = 12
    BANDS = (1.0, 1 / 3, 0.5, 0.7, 1.4, 2.0, 3.0)  # the nominal first: another must do clearly better
    KEEP_MARGIN = 0.03  # once identified, another bandwidth must explain mu this much better (a correlation)

    def __init__(self, rate_hz: float, bandwidth_hz: float, delay_s: float):
        self.rate_hz = rate_hz
        self.nominal_hz = bandwidth_hz
        self.nominal_lag = delay_s * rate_hz
        self.ratio = np.full(self.BUFFER, np.nan)
        self.mu = np.full(self.BUFFER, np.nan)
        self.count = 0
        self.found: tuple[float, float] | None = None
        self.fit = math.nan  # the correlation of the last identification

    def add(self, ratio: np.ndarray, mu: np.ndarray) -> tuple[float, float] | None:
        """One batch (mu NaN where not sliding); returns a new (bandwidth Hz, delay s) when one was identified.

        Parameters
        ----------
        ratio : numpy.ndarray
            The model's ratio at the measured amplitude, per sample.
        mu : numpy.ndarray
            The measured friction coefficient (NaN where not sliding).

        Returns
        -------
        (float, float) or None
            (bandwidth Hz, delay s) when one was identified.

        Examples
        --------
        >>> import numpy as np
        >>> timing = SensorTiming(1000.0, 300.0, 0.001)
        >>> print(timing.add(np.ones(200), np.full(200, np.nan)))               # nothing slid
        None
        >>> timing.count
        200
        """
        n = len(ratio)
        if n >= self.BUFFER:
            ratio, mu, n = ratio[-self.BUFFER:], mu[-self.BUFFER:], self.BUFFER
        self.ratio = np.concatenate((self.ratio[n:], ratio))
        self.mu = np.concatenate((self.mu[n:], mu))
        before = self.count
        self.count += n
        if not self.nominal_hz > 0:
            return None
        every = self.EVERY if self.found is not None else self.FIRST_EVERY  # until the first: often
        if self.count < self.FIRST or self.count // every == before // every:
            return None
        return self.search()

    def search(self) -> tuple[float, float] | None:
        """Search the bandwidths and delays now: ``(bandwidth_hz, delay_s)`` of the best fit, or None while too few
        samples slid, the ratio barely moved, or no pair explains mu well enough.

        Returns
        -------
        (float, float) or None

        Examples
        --------
        >>> print(SensorTiming(1000.0, 300.0, 0.001).search())                    # no samples yet
        None
        """
        valid = np.isfinite(self.mu) & np.isfinite(self.ratio)
        valid[:self.MAX_LAG + 2] = False  # each lag needs its history
        if valid.sum() < self.FIRST or np.nanstd(self.ratio[valid]) < 0.02:
            return None
        y = self.mu[valid]
        y = y - y.mean()
        best = (-1.0, 0, 0.0, None)
        start = np.nan_to_num(self.ratio, nan=float(np.nanmean(self.ratio)))
        # the bandwidth in use first: another must do clearly better, by more once one was identified (the fits of a
        # busy plan score 0.7-0.9 and their best bandwidth flipped between searches, each flip starting the adaptive
        # model over: issue 43)
        kept = self.nominal_hz if self.found is None else self.found[0]
        margin = 0.01 if self.found is None else self.KEEP_MARGIN
        bands = (kept / self.nominal_hz, *(m for m in self.BANDS if not math.isclose(self.nominal_hz * m, kept)))
        for multiple in bands:
            b, a = lowpass_coefficients(self.nominal_hz * multiple, self.rate_hz)
            filtered = first_order_filter(b, a, start, zi=[(b[1] - a[1]) * start[0]])[0]
            scores = []
            for lag in range(self.MAX_LAG + 1):
                x = np.roll(filtered, lag)[valid]
                x = x - x.mean()
                denominator = math.sqrt(float(x @ x) * float(y @ y))
                scores.append(float(x @ y) / denominator if denominator > 0 else 0.0)  # mu rises with the ratio
            # a periodic texture correlates again a period later: of the lags nearly as good as the best, the
            # nearest the nominal delay
            top = max(scores)
            near = [lag for lag, score in enumerate(scores) if score >= top - 0.02]
            lag = min(near, key=lambda candidate: abs(candidate - self.nominal_lag))
            # the bandwidth in use is left for a clear gain; the others compete among themselves as before
            needed = margin if best[2] == kept else 0.01
            if best[3] is None or scores[lag] > best[0] + needed:
                best = (scores[lag], lag, self.nominal_hz * multiple, scores)
        score, lag, bandwidth, scores = best
        if score < 0.7:  # the ratio explains too little of mu: no identification
            return None
        shift = 0.0
        if 0 < lag < self.MAX_LAG:
            left, middle, right = scores[lag - 1], scores[lag], scores[lag + 1]
            curvature = left - 2.0 * middle + right
            if curvature < 0:
                shift = min(max(0.5 * (left - right) / curvature, -0.5), 0.5)
        self.fit = score
        self.found = (bandwidth, (lag + shift) / self.rate_hz)
        return self.found


class FrictionEstimator:
    """See the module docstring. ``model``: the host's friction model (``relative_friction(a, F)``).

    Examples
    --------
    Sensors reading exactly the host model's friction (mu0 = 1) while sliding at 100 mm/s: the estimate slides
    and finds mu0 near 1 (the host's sensor model lags the readings a little):

    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> model = StretchedExponentialModel()
    >>> estimator = FrictionEstimator(model, sensor_rate_hz=1000.0)
    >>> amplitude, force = np.tile(np.linspace(0.0, 5.0, 100), 4), np.full(400, 0.5)
    >>> lateral = model.relative_friction(amplitude, 0.5) * force
    >>> _ = estimator.update(0, amplitude, force, lateral, panel_speed_mm_s=100.0)
    >>> estimator.estimate.state, 0.9 < estimator.mu0 < 1.1
    ('sliding', True)
    """

    def __init__(self, model, settings: EstimatorSettings | None = None, sensor_rate_hz: float = 1000.0):
        self.model = model
        self.settings = settings = settings or EstimatorSettings()
        self.sensor_rate_hz = float(sensor_rate_hz)
        # each parameter's random walk, per sample: q = (1 / (memory x rate x regressor))², the memory of a scalar
        # Kalman filter at that regressor and unit noise
        self.process_noise = tuple((1.0 / (memory * self.sensor_rate_hz * REGRESSOR)) ** 2
                                   for memory in (settings.mu0_memory_s, settings.scale_memory_s))
        self.theta = np.array([math.log(settings.prior_mu0), 0.0])  # ln mu0, ln k
        self.covariance = INITIAL_COVARIANCE.copy()
        self._sensors = SensorModel(3, self.sensor_rate_hz, settings.sensor_bandwidth_hz, settings.sensor_delay_s)
        self.timing = SensorTiming(self.sensor_rate_hz, settings.sensor_bandwidth_hz, settings.sensor_delay_s)
        self._next_sample: int | None = None
        self._force_state = math.nan
        self._force_alpha = math.exp(-1.0 / (0.02 * self.sensor_rate_hz))  # the force, smoothed over 20 ms
        self._confirmed = 0  # consecutive sliding samples
        self._confirm = max(1, int(round(settings.confirm_s * self.sensor_rate_hz)))
        self.estimate = FrictionEstimate(mu0=settings.prior_mu0)
        self._dynamics = getattr(model, "dynamics", None)  # a model with friction dynamics: the finger lags
        law = getattr(model, "speed_law", None)  # a settled speed law: the model's amplitude axis scales with speed
        self._speed_law = law if law is not None and law.exponent > 0.0 else None
        self._felt = np.ones(3)  # the ratio, slope and intended ratio through those dynamics: their states

    def __repr__(self) -> str:
        e = self.estimate
        return (f"FrictionEstimator({getattr(self.model, 'name', 'model')}: {e.state}, mu0 {e.mu0:.3g}, "
                f"scale {e.scale:.3g}, {e.sliding_samples} sliding samples)")

    @property
    def mu0(self) -> float:
        """The friction coefficient without vibration, as estimated.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> FrictionEstimator(StretchedExponentialModel()).mu0 == EstimatorSettings().prior_mu0        # the prior
        True
        """
        return math.exp(self.theta[0])

    @property
    def scale(self) -> float:
        """k, the estimated stretch of the model's amplitude axis (1: the model as it is).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> FrictionEstimator(StretchedExponentialModel()).scale                   # the model as it is
        1.0
        """
        return math.exp(self.theta[1])

    @property
    def sensor_timing(self) -> tuple[float, float]:
        """The force sensors' bandwidth (Hz) and delay (s) the estimator models them with now (the nominal ones until
        :class:`SensorTiming` identifies others).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> FrictionEstimator(StretchedExponentialModel()).sensor_timing
        (300.0, 0.001)
        """
        return self._sensors.bandwidth_hz, self._sensors.delay_s

    def predicted_ratio(self, amplitude_um_pp, force_n) -> np.ndarray:
        """The adapted model's ratio: r(a / k, F).

        Parameters
        ----------
        amplitude_um_pp : array_like
            µm p-p.
        force_n : array_like
            N.

        Returns
        -------
        numpy.ndarray

        Examples
        --------
        At scale 1 the stretched law at a = s0 and 0.5 N: d + (1 - d)/e:

        >>> import math
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> ratio = FrictionEstimator(model).predicted_ratio([model.scale_um_pp], 0.5)
        >>> round(float(ratio[0]), 6), round(0.1 + 0.9 / math.e, 6)
        (0.431091, 0.431091)
        """
        return self.model.relative_friction(np.asarray(amplitude_um_pp, dtype=float) / self.scale, force_n)

    def _fault(self, reason: str, first_sample: int, n: int) -> BatchResult:
        self._confirmed = 0
        self._next_sample = None  # the filters start over after a fault
        self.estimate = FrictionEstimate("fault", reason, self.mu0, self.scale, math.nan, math.nan,
                                         self.estimate.sliding_samples, first_sample + n - 1)
        nothing = np.full(n, np.nan)
        return BatchResult(nothing, nothing, np.zeros(n), np.zeros(n, dtype=bool), self.estimate)

    def update(self, first_sample: int, amplitude_um_pp, normal_force_n, lateral_force_n,
               panel_speed_mm_s: float | None = None, correction: float = 0.0) -> BatchResult:
        """One batch of consecutive sensor samples from sample number ``first_sample``; ``panel_speed_mm_s``:
        the finger's speed as the touch panel says (None: unknown); ``correction``: the controller's fast
        correction g (its amplitudes are k (1 + g) times the model's). Returns the per-sample figures and
        updates :attr:`estimate`.

        Parameters
        ----------
        first_sample : int
            The first sample's number.
        amplitude_um_pp, normal_force_n, lateral_force_n : array_like
            Per sample: µm p-p, N, N.
        panel_speed_mm_s : float, optional
            The finger's speed, mm/s.
        correction : float
            The controller's fast correction g.

        Returns
        -------
        BatchResult

        Examples
        --------
        A force sensor reading NaN is a fault, said in words:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> estimator = FrictionEstimator(StretchedExponentialModel())
        >>> result = estimator.update(0, np.zeros(3), np.full(3, np.nan), np.zeros(3))
        >>> result.estimate.state, result.estimate.reason, int(result.used.sum())
        ('fault', 'a sensor reads NaN', 0)
        """
        a = np.asarray(amplitude_um_pp, dtype=float)
        force = np.asarray(normal_force_n, dtype=float)
        lateral = np.abs(np.asarray(lateral_force_n, dtype=float))  # friction opposes the motion, either way
        n = len(a)
        if n == 0:
            return BatchResult(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool), self.estimate)
        if not (np.isfinite(a).all() and np.isfinite(force).all() and np.isfinite(lateral).all()):
            return self._fault("a sensor reads NaN", first_sample, n)
        if force.min() < MIN_NORMAL_N or force.max() > MAX_FORCE_N or lateral.max() > MAX_FORCE_N:
            return self._fault("a force sensor reads out of range", first_sample, n)
        if a.min() < -0.5:
            return self._fault("the amplitude sensor reads out of range", first_sample, n)
        s = self.settings
        a = np.maximum(a, 0.0)
        # with a settled speed law, the model at the panel's speed (the reference speed's scale when unknown), as the
        # renderer's inverse was: the reset below and the model's values further down alike
        law = self._speed_law
        at_speed = self.scale * (law.one_scale(panel_speed_mm_s) if law is not None and panel_speed_mm_s is not None
                                 else 1.0)
        fresh = self._next_sample is None or first_sample != self._next_sample
        if fresh:  # the start, or samples were lost
            settled = float(self.model.relative_friction(a[0] / at_speed, max(force[0], s.min_force_n)))
            self._sensors.reset(np.array([settled, 0.0, settled]))
            self._force_state = float(force[0])
        self._next_sample = first_sample + n
        smooth, _ = first_order_filter([1.0 - self._force_alpha], [1.0, -self._force_alpha], force,
                            zi=[self._force_alpha * self._force_state])
        self._force_state = float(smooth[-1])
        model_force = np.maximum(smooth, s.min_force_n)
        # the model and its slope in ln k at the present scale (and speed), as the force sensors would see them
        u = a / at_speed
        h = DIFFERENCE_STEP
        try:
            ratio = self.model.relative_friction(u, model_force)
            slope = (self.model.relative_friction(u * math.exp(-h), model_force)
                     - self.model.relative_friction(u * math.exp(h), model_force)) / (2.0 * h)
            intended = self.model.relative_friction(u / (1.0 + correction), model_force)
        except ModelError as error:
            return self._fault(f"the model refused the sensors' values ({error})", first_sample, n)
        if self._dynamics is not None:
            if fresh:
                self._felt[:] = (ratio[0], slope[0], intended[0])
            ratio, slope, intended = self._felt_through_dynamics(ratio, slope, intended, panel_speed_mm_s)
        ratio_seen, slope_seen, intended_seen = self._sensors(np.vstack((ratio, slope, intended)))
        mu = lateral / np.maximum(force, s.min_force_n)
        mu0 = self.mu0
        predicted = mu0 * ratio_seen
        state, reason = self._classify(median(force), panel_speed_mm_s, mean(mu), mean(predicted))
        used = np.zeros(n, dtype=bool)
        if state == "sliding":
            self._confirmed += n
            if self._confirmed >= self._confirm:
                used[:] = force >= s.min_force_n
        else:
            self._confirmed = 0
        if s.identify_sensors:
            found = self.timing.add(ratio, np.where(used, mu, np.nan))
            if found is not None:
                bandwidth, delay = found
                if (abs(delay - self._sensors.delay_s) * self.sensor_rate_hz > 0.25
                        or abs(math.log(bandwidth / max(self._sensors.bandwidth_hz, 1e-9))) > 0.1):
                    # what was fitted through the old timing: learn the scale again; mu0 keeps what pinned it
                    self.covariance[1, 1] = max(self.covariance[1, 1], INITIAL_COVARIANCE[1, 1])
                    self.covariance[0, 1] = self.covariance[1, 0] = 0.0
                self._sensors.set(bandwidth, delay)
        # the fit waits for the sensors' timing, unless the ratio is steady (then timing does not matter)
        swing = float(np.maximum.reduce(ratio) - np.minimum.reduce(ratio))  # np.ptp's value
        timed = not s.identify_sensors or self.timing.found is not None or swing < 0.02
        if used.any() and timed:
            self._fit(mu[used], predicted[used], mu0 * slope_seen[used], force[used])
        elif used.any():
            state, reason = "waiting", "sliding: learning the force sensors' timing"
        if state == "sliding" and not used.any():
            state, reason = "waiting", "sliding: confirming"
        if state == "waiting":
            used[:] = False
        mu0 = self.mu0
        measured = np.where(used, mu / mu0, np.nan)
        # the sensitivity of the ratio to the amplitude's log: -(slope in ln k), as the sensors see it
        sensitivity = np.where(used, -slope_seen, 0.0)
        count = self.estimate.sliding_samples + int(np.count_nonzero(used))
        self.estimate = FrictionEstimate(state, reason, mu0, self.scale, self._force_state,
                                         nan_mean(measured) if used.any() else math.nan, count,
                                         first_sample + n - 1)
        return BatchResult(measured, np.where(used, intended_seen, np.nan), sensitivity, used, self.estimate)

    def _felt_through_dynamics(self, ratio: np.ndarray, slope: np.ndarray, intended: np.ndarray,
                               speed_mm_s: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The model's static ratio, its slope and the intended ratio as the finger feels them: each sample's
        value followed with the onset's time constant where the ratio falls below the felt one, the recovery's
        (at the finger's speed; the dynamics' reference speed when unknown) where it rises. The slope and the
        intended ratio follow with the ratio's time constants: the felt ratio's sensitivity, and the ratio
        meant, through the same lag."""
        dynamics, rate = self._dynamics, self.sensor_rate_hz
        speed = speed_mm_s if speed_mm_s is not None and speed_mm_s > 0 else dynamics.reference_speed_mm_s
        felt = dynamics.respond(ratio, rate, speed, felt=float(self._felt[0]))
        before = np.concatenate(([self._felt[0]], felt[:-1]))
        falling = math.exp(-1.0 / (rate * dynamics.onset_s))
        rising = math.exp(-1.0 / (rate * float(dynamics.recovery_at_s(speed))))
        alpha = np.where(ratio < before, falling, rising)
        lagged = []
        for row, state in ((slope, float(self._felt[1])), (intended, float(self._felt[2]))):
            out = np.empty(len(row))
            for k, (x, keep) in enumerate(zip(row.tolist(), alpha.tolist(), strict=True)):
                state = keep * state + (1.0 - keep) * x
                out[k] = state
            lagged.append(out)
        self._felt[:] = (felt[-1], lagged[0][-1], lagged[1][-1])
        return felt, lagged[0], lagged[1]

    def _classify(self, force_n: float, speed_mm_s: float | None, mu_mean: float, predicted_mean: float):
        s = self.settings
        if force_n < s.min_force_n:
            return "lifted", f"the finger is off the plate ({force_n:.2f} N)"
        if speed_mm_s is not None and speed_mm_s < s.min_speed_mm_s:
            return "resting", "the finger stands still (touch panel)"
        if mu_mean < s.resting_fraction * predicted_mean:
            return "resting", "the finger sticks (no friction measured)"
        return "sliding", "sliding"

    def _fit(self, mu: np.ndarray, predicted: np.ndarray, slope: np.ndarray, force: np.ndarray) -> None:
        """Recursive least squares in (ln mu0, ln k) over these samples, linearised at the batch's start, each
        parameter a random walk (:attr:`process_noise`)."""
        if not len(mu):
            return
        theta = self.theta
        p = self.covariance
        q0, q1 = self.process_noise
        weight = force / self.settings.reference_force_n  # the noise of mu goes as 1/F
        p00, p01, p11 = p[0, 0], p[0, 1], p[1, 1]
        t0, t1 = theta[0], theta[1]
        for y, yhat, d, w in zip(mu.tolist(), predicted.tolist(), slope.tolist(), weight.tolist(), strict=True):
            phi0, phi1 = yhat * w, d * w  # d(mu)/d(ln mu0) = mu, d(mu)/d(ln k) = mu0 dr/d(ln k)
            error = (y - yhat) * w
            g0 = p00 * phi0 + p01 * phi1
            g1 = p01 * phi0 + p11 * phi1
            denominator = 1.0 + phi0 * g0 + phi1 * g1
            k0, k1 = g0 / denominator, g1 / denominator
            t0 += k0 * error
            t1 += k1 * error
            p00, p01, p11 = p00 - k0 * g0, p01 - k0 * g1, p11 - k1 * g1
            if p00 + p11 < MAX_COVARIANCE:  # the random walks, within the bound
                p00 += q0
                p11 += q1
        theta[0] = min(max(t0, LN_MU0_RANGE[0]), LN_MU0_RANGE[1])
        theta[1] = min(max(t1, LN_K_RANGE[0]), LN_K_RANGE[1])
        p[0, 0], p[0, 1], p[1, 0], p[1, 1] = p00, p01, p01, p11
