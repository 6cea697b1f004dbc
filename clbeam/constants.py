"""Instrument defaults, physical limits and detection thresholds, each defined once.

Every module that needs one of these numbers imports it from here, so a
default (the paper's 0.25 coherence threshold, the SBP29 band) or a limit
(the sound speeds a ping file may hold) changes in one place.
"""

# -- the SBP29-class instrument (Holland et al. 2024, Section II) -----------
#: receive elements across-track
SBP29_N_ELEMENTS = 64
#: receive array width across-track (m)
SBP29_ARRAY_WIDTH_M = 3.528
#: LFM pulse band (Hz): 2-9 kHz
SBP29_BAND_HZ = (2000.0, 9000.0)
#: band centre (Hz)
SBP29_CENTRE_FREQUENCY_HZ = 0.5 * (SBP29_BAND_HZ[0] + SBP29_BAND_HZ[1])
#: LFM pulse length of the reference scene (s)
SBP29_PULSE_DURATION_S = 0.08
#: along-track length of the transmit column used: 16 of the 7 m column's 32 elements (m)
SBP29_TX_LENGTH_M = 3.5
#: sample rate of the reference scene (Hz)
SBP29_SAMPLE_RATE_HZ = 40000.0

# -- media (docs/simulator.md) ----------------------------------------------
#: isospeed sound speed of the reference scene (m/s)
SOUND_SPEED_M_S = 1500.0
#: sound speeds a ping file, an option or a water profile may hold (m/s)
WATER_SPEED_RANGE_M_S = (1300.0, 1700.0)
#: sound speeds a profile may hold once it reaches into the sediment (m/s)
PROFILE_SPEED_RANGE_M_S = (1300.0, 2000.0)
#: sediment interval velocities an option may give (m/s)
SEDIMENT_SPEED_RANGE_M_S = (1300.0, 2000.0)

# -- ping-file limits (docs/ping-format.md) ------------------------------------
#: largest roll a ping may carry (degree)
MAX_ABS_ROLL_DEG = 45.0
#: largest distance (m) of an element or the source from the array reference point
MAX_OFFSET_M = 100.0
#: largest channel gain correction (dB) a ping file may give
MAX_ABS_GAIN_DB = 60.0

# -- accuracy -----------------------------------------------------------------
#: default error budget of the intensity against the exact image (dB): picks mode, upsampling and beams
DEFAULT_MAX_ERROR_DB = -40.0
#: error budget of the coherence factor (largest |dCF| on cells within 40 dB of an echo) that --interp auto holds
DEFAULT_MAX_CF_ERROR = 0.02

# -- detection (docs/peaks.md; Holland et al. 2024, Section III) ----------------
#: coherence-peak threshold on the smoothed CF (the paper's 0.25)
PEAK_THRESHOLD = 0.25
#: CF (and peaks) only in cells summed from at least this fraction of the usable channels
DEFAULT_MIN_CHANNELS = 0.5
#: peaks only this far above the ping's noise floor (dB; clbeam.imaging.detection)
DEFAULT_MIN_SNR_DB = 6.0
#: peaks only this far above the mean intensity of the cells around them (dB; clbeam.imaging.detection)
DEFAULT_MIN_CONTRAST_DB = 12.0
#: CF threshold of persistence maps and of the survey association (paper Figs. 9-10)
MAP_THRESHOLD = 0.4

# -- navigation ---------------------------------------------------------------
#: one knot (m/s)
KNOT_M_S = 1852.0 / 3600.0
#: WGS84 ellipsoid: semi-major axis (m) and flattening
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563

# -- seabed backscatter (AVO) -----------------------------------------------------
#: consecutive pings stacked per patch and side by default
AVO_PINGS_PER_PATCH = 30
