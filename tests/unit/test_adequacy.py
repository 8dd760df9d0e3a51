"""The inadequacy alarm on the paper's two regimes (the contrast experiment's measured mismatches)."""

from torchpaml.analysis import assess_adequacy


def test_alpha4_is_adequate_and_alpha10_raises_the_alarm():
    # results/contrast, two-stage Chebyshev: alpha 4 physics 12.12 % -> hybrid 2.01 % (train), 10.71 -> 6.22
    adequate = assess_adequacy(0.1212, 0.0201, 0.1071, 0.0622)
    assert not adequate.inadequate and adequate.message.startswith("physics adequate")
    # alpha 10: 90.0 % -> 54.2 % on training (closes 40 %), and 126 % on validation against the physics' 102 %
    alarm = assess_adequacy(0.8996, 0.5419, 1.0190, 1.2637)
    assert alarm.inadequate and "PHYSICS INADEQUATE" in alarm.message
    assert "closes only 40 %" in alarm.message and "no better than the physics" in alarm.message


def test_either_condition_alone_raises_it():
    assert assess_adequacy(0.5, 0.3).inadequate  # closes only 40 % of the training error
    assert assess_adequacy(0.5, 0.1, 0.5, 0.6).inadequate  # fits training, worse on validation
    assert not assess_adequacy(0.5, 0.1, 0.5, 0.3).inadequate


def test_noise_is_a_residual_the_orthogonal_residual_cannot_reduce():
    # make demo, last rung: 1.95 % -> 1.86 % on training, linearly uncorrelated with the input: complete
    complete = assess_adequacy(0.0195, 0.0186, 0.0199, 0.0436, residual_white=True)
    assert not complete.inadequate and complete.message.startswith("physics complete at this noise level")
    # make demo, the linear oscillator: friction is odd in the input, so its linear correlation is small, but the
    # hybrid takes 15.2 % to 5.4 % on training and fails validation (84.3 % against 13.5 %): the alarm, not noise
    alarm = assess_adequacy(0.1518, 0.0537, 0.1354, 0.8434, residual_white=True)
    assert alarm.inadequate and "no better than the physics" in alarm.message


def test_an_adequate_hybrid_over_a_residual_that_a_linear_filter_explains_is_covering():
    # the linear oscillator on multisine records of the oscillator with a 6-sample input lag: the hybrid takes
    # 20.1 % to 1.9 % on training and 20.7 % to 14.2 % on validation, "adequate"; a linear filter of the input
    # explains 63 % of the physics' residual (0.22 at most for the library's static effects)
    covering = assess_adequacy(0.2008, 0.0191, 0.2065, 0.1416, linear_share=0.63)
    assert not covering.inadequate and covering.covering
    assert "may be covering a missing dynamic effect" in covering.message and "input_lag" in covering.message
    assert not assess_adequacy(0.2008, 0.0191, 0.2065, 0.1416, linear_share=0.22).covering
    assert not assess_adequacy(0.2008, 0.0191, 0.2065, 0.1416).covering  # not measured
    alarm = assess_adequacy(0.5, 0.3, linear_share=0.9)  # inadequate already: the alarm, not the caveat
    assert alarm.inadequate and not alarm.covering


def test_complete_only_at_the_records_noise_floor():
    # the pendulum with a cubic damping behind quadratic_damping and dynamic_friction: training 1.3 %,
    # white, and the residual reduces nothing; validation 2.14 % against a floor of 1 %: not complete, and the
    # verdict says how far above the floor it is
    above = assess_adequacy(0.013, 0.0129, 0.0214, 0.0214, residual_white=True, noise_floor=0.010)
    assert not above.complete and above.inadequate and above.noise_floor == 0.010
    assert "on validation it is 2.14 times the noise floor read from the records (2.14 % against 1.00 %)" \
        in above.message
    at = assess_adequacy(0.0102, 0.0101, 0.0115, 0.0116, residual_white=True, noise_floor=0.010)  # 1.15 times
    assert at.complete and "1.15 times the noise floor" in at.message
    assert assess_adequacy(0.0102, 0.0101, 0.0120, 0.0121, residual_white=True, noise_floor=0.010).complete  # 1.2
    assert not assess_adequacy(0.0102, 0.0101, 0.0121, 0.0122, residual_white=True, noise_floor=0.010).complete
    assert "more than 1000 times" in assess_adequacy(0.5, 0.3, 0.5, 0.4, noise_floor=0.0).message


def test_under_coloured_noise_the_training_residual_is_the_floor_the_validation_must_stay_within():
    """Noise that is not white reads low by differences (0.55 % for 2 % AR(0.9) noise): where the training residual
    is noise above 1.2 times that floor, the validation mismatch is held to 1.2 times the training one instead."""
    coloured = assess_adequacy(0.0200, 0.0199, 0.0200, 0.0201, residual_white=True, noise_floor=0.0055)
    assert coloured.complete and not coloured.inadequate
    assert "shows to read low" in coloured.message and "1.00 times its training mismatch" in coloured.message
    # a stand-in that fits the training record through its own states: validation above 1.2 times training
    stand_in = assess_adequacy(0.0200, 0.0199, 0.0245, 0.0246, residual_white=True, noise_floor=0.0055)
    assert not stand_in.complete and stand_in.inadequate
    # a residual that is not noise is never excused so
    assert not assess_adequacy(0.0200, 0.0199, 0.0200, 0.0201, noise_floor=0.0055).complete
