//! Settings of one simulated gimbal: what a real unit has fixed in its
//! firmware and mechanics, and what the protocol leaves to the maker
//! (implemented presets, maximum data rate, the unit of Table 10 limits).

use sagebrush_protocol::{DataRate, Identity};

/// One simulated gimbal's configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct GimbalConfig {
    /// Device address 1..=254 on its port (Table 2); `#NN` changes it.
    pub device: u8,
    /// Own group address, when the device knows it (`None`: any group).
    pub group: Option<u8>,
    /// Own port address, when known (`None`: any port).
    pub port: Option<u8>,
    /// Device name of the ID block (Table 6), at most 20 characters.
    pub name: String,
    /// Serial number of the ID block (Table 6), at most 20 characters.
    pub serial: String,
    /// Protocol revision characters of the ID block (Table 6).
    pub revision: [u8; 2],
    /// How long the `IX` initialisation sequence takes (Table 9), milliseconds.
    pub init_ms: u64,
    /// Whether the unit starts initialised (as after its power-up sequence);
    /// otherwise Table 5 bits 0 and 1 are set until `IX`.
    pub start_initialized: bool,
    /// Presets implemented, 1..=256 (numbers `00` .. `presets-1`); the rest answer NIC (1.6.1).
    pub presets: u16,
    /// Whether a preset never stored (`Snn`) answers NIC to its query and
    /// recall, as some units do (issue 48: a gimbal that answers NIC for
    /// preset 00 while another is stored); otherwise every implemented
    /// preset starts at home.
    pub unset_presets_nic: bool,
    /// Fastest rate, hundredths of a degree per second: proportional speed F (Table 11).
    pub max_rate: u16,
    /// Initial discrete rate of both axes (Table 12).
    pub rate: u16,
    /// Initial acceleration of both axes (Table 12).
    pub accel: u16,
    /// Mechanical pan travel (clockwise end, counter-clockwise end), hundredths of a degree.
    pub pan_range: (i16, i16),
    /// Mechanical tilt travel (down end, up end), hundredths of a degree.
    pub tilt_range: (i16, i16),
    /// Hundredths of a degree per count of a Table 10 software limit. The
    /// protocol gives no unit (protocol-notes E9); this is the simulator's choice.
    pub limit_unit: u16,
    /// Highest data rate the unit supports (`B?`, Table 4).
    pub max_data_rate: DataRate,
    /// Milliseconds a lens function takes end to end at speed 9 (Table 16).
    pub lens_travel_ms: u64,
    /// Camera and lens power at start (`CN` / `CX`).
    pub camera_on: bool,
}

impl Default for GimbalConfig {
    fn default() -> Self {
        Self {
            device: 1,
            group: None,
            port: None,
            name: "Sagebrush SIM".into(),
            serial: "SIM-0001".into(),
            revision: *b"19",
            init_ms: 3000,
            start_initialized: true,
            presets: 64,
            unset_presets_nic: false,
            max_rate: 12000,
            rate: 6000,
            accel: 12000,
            pan_range: (-18000, 18000),
            tilt_range: (-9000, 9000),
            limit_unit: 10,
            max_data_rate: DataRate::Bps115200,
            lens_travel_ms: 2000,
            camera_on: true,
        }
    }
}

impl GimbalConfig {
    /// A default gimbal at `device`.
    pub fn at(device: u8) -> Self {
        Self {
            device,
            ..Self::default()
        }
    }

    /// Names the first setting that cannot work.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=254).contains(&self.device) {
            return Err(format!("device address {} is not within 1..=254", self.device));
        }
        Identity::new(self.device, self.revision, self.name.as_bytes(), self.serial.as_bytes()).map_err(|e| {
            format!(
                "ID block of device {}: {e} (printable ASCII, no trailing space)",
                self.device
            )
        })?;
        if !(1..=256).contains(&self.presets) {
            return Err(format!("presets {} is not within 1..=256", self.presets));
        }
        if self.max_rate == 0 || self.rate == 0 || self.accel == 0 {
            return Err("rates and acceleration must be above 0".into());
        }
        for (what, (lo, hi)) in [("pan", self.pan_range), ("tilt", self.tilt_range)] {
            if lo > 0 || hi < 0 || lo >= hi {
                return Err(format!("{what} range {lo}..{hi} must contain 0 and be non-empty"));
            }
        }
        if self.limit_unit == 0 {
            return Err("limit unit must be above 0".into());
        }
        if self.max_data_rate.bits_per_second().is_none() {
            return Err("maximum data rate must be one of C0..C7".into());
        }
        Ok(())
    }
}
