"""
Contact surfaces in MuJoCo's terms: a coefficient of restitution as the solref that bounces so.

Shared by the editor (``set_restitution``, a world's own setting) and the SDF reader (a
collision's ``<bounce>``), so that one formula, measured once, gives every bounce.
"""

import math

#: Contact time constant used with a restitution (s): long enough that a 1-5 ms step resolves
#: the bounce without gaining energy (shorter ones do, above e = 0.5).
RESTITUTION_TIMECONST = 0.04
MAX_RESTITUTION = 0.8
#: The damped spring of timeconst 0.04 s bounces higher than the textbook formula says at low e
#: (gravity acts during the long contact); this linear correction, measured for drops of
#: 0.3-3 m with 1-5 ms steps and every integrator, keeps the bounce within 0.06 of e.
RESTITUTION_CORRECTION = 0.12


def restitution_to_solref(restitution: float) -> list:
    """
    Return MuJoCo solref (timeconst, dampratio) whose bounce has coefficient of restitution e.

    A linear spring-damper gives e = exp(-zeta pi / sqrt(1 - zeta^2)), so
    zeta = -ln(e') / sqrt(pi^2 + ln(e')^2), with e' = e - 0.12 (0.8 - e) correcting for the
    long contact; e = 0 is critically damped (zeta = 1, MuJoCo's default). Above
    :data:`MAX_RESTITUTION` it bounces as 0.8 does.
    """
    e = min(max(restitution - RESTITUTION_CORRECTION * (MAX_RESTITUTION - restitution), 1e-4),
            MAX_RESTITUTION)
    ln_e = math.log(e)
    return [RESTITUTION_TIMECONST, min(1.0, -ln_e / math.sqrt(math.pi ** 2 + ln_e ** 2))]
