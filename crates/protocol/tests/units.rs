//! Table 12 unit types: rates and accelerations in their physical units.
use sagebrush_protocol::{Acceleration, Rate};

#[test]
fn rates_and_accelerations_convert_both_ways_and_refuse_what_the_wire_cannot_carry() {
    assert_eq!(Rate::from_degrees_per_second(20.0), Ok(Rate(2000)));
    assert_eq!(
        Rate::from_degrees_per_second(0.125),
        Ok(Rate(13)),
        "rounded to the nearest hundredth"
    );
    assert_eq!(Rate::from_degrees_per_second(655.35), Ok(Rate(65535)));
    assert_eq!(Rate(1234).degrees_per_second(), 12.34);
    assert_eq!(
        Acceleration::from_degrees_per_second_squared(2.5),
        Ok(Acceleration(250))
    );
    assert_eq!(Acceleration(250).degrees_per_second_squared(), 2.5);
    for bad in [-1.0, 655.36, 1e9, f64::NAN] {
        let e = Rate::from_degrees_per_second(bad).expect_err("out of range");
        assert_eq!((e.min, e.max), (0, 65535), "{bad}");
        assert!(e.to_string().contains("degrees per second"), "{e}");
        assert!(Acceleration::from_degrees_per_second_squared(bad).is_err(), "{bad}");
    }
}
