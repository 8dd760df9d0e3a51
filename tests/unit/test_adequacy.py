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
