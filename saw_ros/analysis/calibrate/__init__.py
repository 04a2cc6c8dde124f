"""
Fit unknown model parameters to measured speeds and advance ratios (``saw-ros calibrate``).

Targets are conditions (slope, motor voltage or helix frequency) with a measured speed or AR: a
CSV in the format of ``msg_config/reference_paper.csv`` or of the footage campaign's
``footage.csv``, or the shipped default, the numbers the paper states (its three measured speeds
and the level and vertical AR of Figure 21 at constant 1 Hz, claims A1 and A2).

The optimiser is CMA-ES (the ``cmaes`` package) in normalised coordinates: every parameter maps
its bounds onto [0, 1] (logarithmically for those spanning a factor of 4 or more, e.g. a
stiffness), so one step size fits all. One generation is one batch of our engine: every candidate
under every target condition, stepped together by ``core.dynamics.simulate`` (candidates that
change the robot's geometry go in batches of their own, the engine steps one robot at a time).
The objective is the mean squared relative error over the targets.

After every generation the state (generation, the pickled optimiser, the best candidate so far,
the history) is written to the output folder; ``resume`` continues from it and, because the
optimiser's random generator is reseeded from (seed, generation) before every generation, ends
where an uninterrupted run with the same seed would.

The uncertainty is local and says what it is: the relative change of every target per relative
change of every parameter at the optimum (central differences, one batch), and from it a
linearised covariance of the parameters for a target error of the fit's own RMS residual (at
least 2 %): which parameters the targets pin down, which directions are flat, which pairs trade
off against each other. The spread of CMA-ES's last population is reported beside it.
No rclpy import.

Modules, in the order a run uses them: ``targets`` (what is measured), ``parameters`` (what is
fitted, within which bounds), ``model`` (the batch that simulates candidates under the targets),
``optimise`` (CMA-ES and its saved state), ``uncertainty`` (sensitivity and identifiability),
``run`` (the whole run and its result files), ``plots`` and ``parameter_file`` (the calibrated
copy of msg_config/simulator.yaml). Every public name is importable from here.
"""
from saw_ros.analysis.calibrate.model import FAILED_LOSS, Model, RECORD_EVERY, sweeps_duration
from saw_ros.analysis.calibrate.optimise import (load_state, optimise, parameters_from_config,
                                                 Settings, STATE_FILE, STATE_VERSION,
                                                 targets_from_config)
from saw_ros.analysis.calibrate.parameter_file import (calibrated_yaml, trained_claims_of,
                                                       TRAINED_TAG, write_calibrated_yaml)
from saw_ros.analysis.calibrate.parameters import (DEFAULT_FIT, DEFAULT_PARAMETERS,
                                                   default_parameters, make_parameters,
                                                   MOTOR_PARAMETERS, Parameter)
from saw_ros.analysis.calibrate.plots import write_plots
from saw_ros.analysis.calibrate.run import (calibrate, claims_summary, finish, HISTORY_FILE,
                                            Result, RESULT_FILE, speed_error_pct)
from saw_ros.analysis.calibrate.targets import (CalibrationError, load_targets, PAPER_AR,
                                                paper_targets, Target)
from saw_ros.analysis.calibrate.uncertainty import (CORRELATED, identifiability,
                                                    IDENTIFIED_REL_STD, MIN_TARGET_ERROR,
                                                    sensitivity, SENSITIVITY_STEP)

__all__ = ['calibrate', 'calibrated_yaml', 'CalibrationError', 'claims_summary', 'CORRELATED',
           'DEFAULT_FIT', 'DEFAULT_PARAMETERS', 'default_parameters', 'FAILED_LOSS', 'finish',
           'HISTORY_FILE', 'identifiability', 'IDENTIFIED_REL_STD', 'load_state', 'load_targets',
           'make_parameters', 'MIN_TARGET_ERROR', 'Model', 'MOTOR_PARAMETERS', 'optimise',
           'PAPER_AR', 'paper_targets', 'Parameter', 'parameters_from_config', 'RECORD_EVERY',
           'Result', 'RESULT_FILE', 'sensitivity', 'SENSITIVITY_STEP', 'Settings',
           'speed_error_pct', 'STATE_FILE', 'STATE_VERSION', 'sweeps_duration', 'Target',
           'targets_from_config', 'trained_claims_of', 'TRAINED_TAG', 'write_calibrated_yaml',
           'write_plots']
