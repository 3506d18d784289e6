"""The independent truth's vehicle library, each vehicle with its sources.

Numbers are the 2D model's: stiffness and damping per wheelset (primary) and per bogie
(secondary), lengths from the carbody centre. Every vehicle carries the seed's Table 2
frequencies where Table 2 lists it *from the same source*; a test checks the library's
rigid-body frequencies (stiff carbody, wheelsets on a rigid rail) against them.

Vehicles of the seed's Table 2 that are left out: ETR500Y (Liu et al. 2009), ICE2
(Domenech et al. 2014), Shinkansen and TGV (Lin et al. 2005), Eurostar (Kouroussis et al.
2011), Pioneer (Antolin et al. 2013), Diana et al. (2002). Their 2D parameter sets were not
found in the references available here, and inventing them would make a frequency check
against Table 2 meaningless.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ... import checks


@dataclass(frozen=True)
class Equipment:
    """An underfloor body: ``mass`` [kg] at ``x`` [m]; on mounts of natural frequency
    ``mount_hz`` [Hz] and damping ratio ``damping_ratio``, or rigidly fixed when ``mount_hz`` is None."""

    name: str
    mass: float
    x: float
    mount_hz: float | None = None
    damping_ratio: float = 0.1

    def __post_init__(self):
        checks.non_negative(self, "mass", "damping_ratio")
        if self.mount_hz is not None:
            checks.positive(self, "mount_hz")


@dataclass(frozen=True)
class Payload:
    """A load drawn per journey: ``capacity`` [kg] filled to a fraction drawn in
    ``fill`` (low, high); carried by the floor (``where`` = "floor") or by the equipment named."""

    name: str
    capacity: float
    fill: tuple[float, float]
    where: str = "floor"

    def __post_init__(self):
        checks.non_negative(self, "capacity")
        lo, hi = self.fill
        if not 0 <= lo <= hi <= 1:
            raise ValueError(f"Payload.fill must satisfy 0 <= low <= high <= 1, got {self.fill!r}")


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle of the library (SI units; 2D model values, see the module docstring).

    ``m_structure`` is the carbody's own mass, spread along the beam (without the
    equipment and payloads listed); ``J_v`` the pitch inertia [kg m^2] its mass
    distribution aims at (with the nominal payload), reachable only within what a beam
    with non-negative mass per length allows; ``bending_hz`` the first free-free bending
    of the carbody beam (uniform-beam closed form)."""

    name: str
    reference: str
    notes: str
    length: float
    m_structure: float
    J_v: float
    bending_hz: float
    m_b: tuple[float, float]
    J_b: float
    m_w: float
    k_p: float
    c_p: float
    k_s: float
    c_s: float
    L_v: float
    L_b: float
    wheel_radius: float = 0.42
    equipment: tuple[Equipment, ...] = ()
    payloads: tuple[Payload, ...] = ()
    table2: dict = field(default_factory=dict)  # seed Table 2 [Hz] when Table 2 cites the same source
    table2_tolerance: float = 0.03

    def __post_init__(self):
        checks.positive(self, "length", "m_structure", "J_v", "bending_hz", "J_b", "m_w", "k_p", "k_s", "L_v",
                        "L_b", "wheel_radius")
        checks.non_negative(self, "c_p", "c_s")
        if len(self.m_b) != 2 or min(self.m_b) <= 0:
            raise ValueError(f"VehicleSpec.m_b must be two positive bogie masses [kg], got {self.m_b!r}")
        if not self.L_b < self.L_v <= self.length / 2:
            raise ValueError(f"VehicleSpec {self.name}: need L_b < L_v <= length/2, got {self.L_b}, {self.L_v}, "
                             f"{self.length}")
        names = {e.name for e in self.equipment}
        for p in self.payloads:
            if p.where != "floor" and p.where not in names:
                raise ValueError(f"VehicleSpec {self.name}: payload {p.name} carried by unknown equipment {p.where!r}")

    def nominal_payload(self) -> dict[str, float]:
        """Mid-range fill of every payload [kg]."""
        return {p.name: p.capacity * 0.5 * sum(p.fill) for p in self.payloads}


INTERCITY = VehicleSpec(
    name="intercity",
    reference="Quirke et al., in-service seed (irish-rail-2d-calibration-fdd-ce.txt): Hyundai-Rotem 22000 "
              "InterCity car, Tables 5-6 (masses, primary and air-spring stiffness, damping), Table 7 (J_b)",
    notes="Tare 35 032 kg (Table 5) less an underfloor powerpack of 2 500 kg (assumed; the seed gives none) is "
          "the carbody beam. Table 5's variable loads are drawn per journey within its ranges. Bogie masses: "
          "trailer 3 087 kg leads (instrumented), drive 2 916 kg (Table 6). k_p = 2.84 MN/m per wheelset and "
          "k_s = 720 kN/m per bogie are Table 7's means (Table 6's 465 + 245 kN/m per spring, 360 kN/m per air "
          "spring). Damping 29.4 kN s/m per wheelset and 45 kN s/m per bogie (Table 6). Assumed typical: L_v = "
          "8.0 m, L_b = 1.2 m, 23 m carbody, 1 400 kg wheelsets, tank positions, first bending 14 Hz (above the band the carbody_bending effect moves it into). The "
          "seed's J_v = 611 000 kg m^2 (Table 7, 'typical values found in the literature') needs a radius of "
          "gyration of 4.0 m, below what any non-negative mass distribution over 23 m gives (at least "
          "L/sqrt(20) = 5.1 m); the beam takes the most centre-heavy distribution allowed instead.",
    length=23.0, m_structure=35_032.0 - 2_500.0, J_v=611_000.0, bending_hz=14.0,
    m_b=(3_087.0, 2_916.0), J_b=3_500.0, m_w=1_400.0,
    k_p=2_840_000.0, c_p=29_400.0, k_s=720_000.0, c_s=45_000.0, L_v=8.0, L_b=1.2, wheel_radius=0.42,
    equipment=(Equipment("powerpack", 2_500.0, -1.5, mount_hz=9.0, damping_ratio=0.12),
               Equipment("fuel_tank", 0.0, 3.0), Equipment("water_tank", 0.0, 6.5),
               Equipment("waste_tank", 0.0, -6.5)),
    payloads=(Payload("passengers", 54 * 80.0, (0.25, 0.75)), Payload("wheelchair", 300.0, (0.0, 1.0)),
              Payload("luggage", 188.0, (0.25, 0.75)), Payload("fuel", 1_612.0, (0.25, 0.75), "fuel_tank"),
              Payload("waste", 650.0, (0.25, 0.75), "waste_tank"),
              Payload("water", 500.0, (0.25, 0.75), "water_tank")),
)

MANCHESTER = VehicleSpec(
    name="manchester",
    reference="Iwnicki (ed.), Manchester benchmarks for rail vehicle simulation, Vehicle System Dynamics 30 "
              "(1998) 295-313: the benchmark coach; per-corner primary 1.2 MN/m and 4 kN s/m, per-corner "
              "secondary 430 kN/m and 20 kN s/m (doubled for the 2D model), bogie centres 2 x 9.5 m, wheelbase "
              "2 x 1.28 m, carbody 32 000 kg and 1.97e6 kg m^2, bogie 2 615 kg and 1 476 kg m^2, wheelset "
              "1 813 kg; as reduced to 2D in Cantero, TTB-2D, SoftwareX 20 (2022)",
    notes="Assumed: 26.4 m carbody (a UIC coach with 19 m bogie centres), first bending 14 Hz; no equipment or "
          "payload (the benchmark is one mass).",
    length=26.4, m_structure=32_000.0, J_v=1.97e6, bending_hz=14.0,
    m_b=(2_615.0, 2_615.0), J_b=1_476.0, m_w=1_813.0,
    k_p=2 * 1.2e6, c_p=2 * 4.0e3, k_s=2 * 430.0e3, c_s=2 * 20.0e3, L_v=9.5, L_b=1.28, wheel_radius=0.46,
    table2={"carbody_bounce": 1.07, "carbody_pitch": 1.28, "bogie_bounce": 7.47, "bogie_pitch": 11.68},
)

VEHICLES: dict[str, VehicleSpec] = {v.name: v for v in (INTERCITY, MANCHESTER)}


def vehicle(name: str) -> VehicleSpec:
    """The library's vehicle ``name``; ValueError naming the ones there are."""
    try:
        return VEHICLES[name]
    except KeyError:
        raise ValueError(f"no vehicle {name!r} in the independent truth's library; have {', '.join(VEHICLES)}") \
            from None
