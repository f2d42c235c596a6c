//! Unit types: Table 12 rates and accelerations in their physical units,
//! Table 4 line rates read from text.
use sagebrush_protocol::{Acceleration, DataRate, NotAProtocolRate, Rate};

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

#[test]
fn a_line_rate_is_read_from_text_and_a_wrong_one_lists_the_rates() {
    assert_eq!("9600".parse::<DataRate>(), Ok(DataRate::Bps9600));
    assert_eq!("115200".parse::<DataRate>(), Ok(DataRate::Bps115200));
    for wrong in ["9601", "", "fast", "-9600", "8"] {
        assert_eq!(wrong.parse::<DataRate>(), Err(NotAProtocolRate), "{wrong:?}");
    }
    assert_eq!(
        NotAProtocolRate.to_string(),
        "expected one of the protocol's rates in bit/s (Table 4): 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200"
    );
}
