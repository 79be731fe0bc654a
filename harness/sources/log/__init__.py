"""A measured joint log as the source of a run, beside the MuJoCo bench: read (`read`), its units made
SI (`units`), checked (`checks`), cut at its gaps (`segments`), conditioned stretch by stretch
(`condition`) and split once into a training span, the only data a fit reads, and a validation span
(`split`, `Split`).

A scenario's `[data]` table names a CSV file and its columns, `{j}` standing for 1..n in the
model's joint order and `{name}` for a joint's name, or a list of column names in joint order:

    [data]
    file = "log.csv"                      # relative to the scenario file; or a list of files, each with
                                          # its own time column, joined on time (join.py)
    columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }   # qd may be left out; or a ROS
                                          # joint_states export's: names = "field.name{index}",
                                          # q = "field.position{index}", ... (indexed.py)
    units = { q = "rad", qd = "rad/s", tau = "N m" }   # or "deg", "deg/s", "current" (default SI, said so);
                                          # t = "s" (default), "ms", "us" or "ns"
    torque_constant = [0.11, ...]         # N m/A per joint (motor side, signed), with tau = "current"
    gear_ratio = [100, ...]               # per joint (signed), with tau = "current"
    cutoff = 10.0                         # Hz, zero-phase low-pass (default: none)
    filter_order = 4                      # Butterworth order (applied forward and backward)
    rate = 1000.0                         # Hz, the uniform grid (default: 1 / the median step)
    decimate = 10                         # keep every 10th sample of the filtered grid (default 1)
    trim = 0.3                            # s dropped at each end of every stretch (default 3 / cutoff)
    gap = 5.0                             # a step over 5 median steps splits the log (default: `split_step`)
    limits_check = true                   # refuse positions far beyond the joint limits (a unit mistake?)
    truth = "bench_robot.toml"            # the model that made the log, where known: errors against it too
    delay = "estimate"                    # the torque channels' lag behind the encoders: or "correct", "none"
    identify_torque_constants = true      # currents: each joint's constant identified (default: with a payload log)
    repeat = 4                            # the fit repeated on 4 disjoint segments of the training span
    payload = { file = "loaded.csv", body = "wrist_3_link", mass = 2.0, com = [...], inertia = [...] }
    validation = { from = 0.7 }           # the last 30 % by time is kept for validation
    velocities = "checked"                # logged q' realigned where it lags the positions (velocity.py); "used"
    counterbalanced = ["torso_lift"]      # channels without gravity (a spring, a counterweight): read so
    unmeasured = ["wrist_2", "wrist_3"]   # joints without a torque channel: their motion kept (channels.py);
                                          # a closed chain's actuated joints, a motor-side log's motors

Instead of `file` and `columns`, `bag` (a rosbag2 folder or a ROS 1 .bag file) and `topic` (its
sensor_msgs/JointState topic) read a ROS bag, matching joints by name (harness/sources/bag.py); a
validation `file` is then a bag too.

Units are converted on reading (`to_si`): degrees of revolute joints to radians; motor currents to
joint torques, tau = i k_t N. A revolute joint whose positions reach UNIT_FACTOR times its limit is
refused, with the unit that would fit suggested; so are velocities that are not the positions' rate
of change (`_check_velocities`: t in milliseconds, q' in deg/s read as rad/s, a column of the other
sign), and a grid over MAX_UPSAMPLING times finer than the log.

Conditioning, in this order, each step stated in results.json (`data.conditioning`), each warning
also printed once on the terminal:
0. reading: a last line cut short (no line end) dropped, said; a value over ABSURD times what the
   model's size allows (`units.plausible`) refused, naming the file, the column and the row;
1. checks, on the whole file: every cell a finite number (else the file, the column and the row are
   named); time strictly increasing once repeated rows are dropped; the velocities against the
   positions' rate of change; rows that repeat the previous row's positions exactly (a logger's
   sample and hold) dropped and counted; steps over twice the median and the clock's jitter
   counted; positions beyond the model's joint limits counted;
2. the log cut at every gap (a step over `split_step`) and, when split by time, at the split: each
   stretch alone goes through steps 3-6, and one too short for them is dropped, said so;
3. resampling of q, q', tau to a uniform grid (the whole file's rate) by linear interpolation;
4. a zero-phase Butterworth low-pass (scipy.signal.sosfiltfilt) of q, q', tau;
5. velocities (where the log has none) and accelerations by central differences of the filtered
   signals (numpy.gradient, second order);
6. `trim` seconds dropped at both ends of the stretch (filter and difference transients: the guard
   band at every gap and at the split), then decimation.
Nothing of the validation span reaches the training span; the two are checked disjoint. The file's
sha256 is recorded. A closed chain's log holds its actuated joints' channels: they are read and
conditioned as above, and every other joint's motion follows from the loops at every conditioned
row (`closed`).
"""

from harness.sources.log.read import check_columns
from harness.sources.log.schema import DataSource, KnownPayload, read_source
from harness.sources.log.split import LOG_FILE, Split, load, load_payload

__all__ = ["LOG_FILE", "DataSource", "KnownPayload", "Split", "check_columns", "load", "load_payload", "read_source"]
