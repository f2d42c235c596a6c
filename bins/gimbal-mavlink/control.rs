//! Who may command a gimbal (Gimbal Protocol v2, "Gimbal Manager Control"):
//! MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE sets the primary and secondary
//! control owners (param1/2 and param3/4: a system and component id, -1
//! leaves it, -2 sets the sender, -3 releases it if the sender holds it).
//! While nobody holds control any component may command; once a
//! component holds it, commands from any other are denied, and taking
//! control from another owner is denied until it releases (the primary
//! owner may also clear the secondary).

/// A MAVLink system and component id.
pub type Sender = (u8, u8);

/// The control owners of one gimbal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Control {
    pub primary: Option<Sender>,
    pub secondary: Option<Sender>,
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// Another component holds control.
    HeldByAnother,
    /// A parameter is none of the values the command defines.
    BadParameter,
}

/// One owner slot's request, from a pair of CONFIGURE parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    Leave,
    Take(Sender),
    Release,
}

fn slot(sysid: f32, compid: f32, sender: Sender) -> Result<Slot, Refused> {
    let whole = |v: f32| v.is_finite() && v.fract() == 0.0;
    if !whole(sysid) || !whole(compid) {
        return Err(Refused::BadParameter);
    }
    Ok(match sysid as i64 {
        -1 => Slot::Leave,
        -2 => Slot::Take(sender),
        -3 => Slot::Release,
        s @ 0..=255 if (0.0..=255.0).contains(&compid) => {
            if s == 0 {
                Slot::Release
            } else {
                Slot::Take((s as u8, compid as u8))
            }
        }
        _ => return Err(Refused::BadParameter),
    })
}

impl Control {
    /// Whether `sender` may command the gimbal now.
    pub fn allows(&self, sender: Sender) -> bool {
        match (self.primary, self.secondary) {
            (None, None) => true,
            (p, s) => p == Some(sender) || s == Some(sender),
        }
    }

    /// MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE from `sender`; all or nothing.
    pub fn configure(&mut self, sender: Sender, params: [f32; 4]) -> Result<(), Refused> {
        let primary = slot(params[0], params[1], sender)?;
        let secondary = slot(params[2], params[3], sender)?;
        let mut next = *self;
        for (request, owner) in [(primary, &mut next.primary), (secondary, &mut next.secondary)] {
            match request {
                Slot::Leave => {}
                Slot::Take(who) => {
                    if owner.is_some_and(|o| o != sender && o != who) {
                        return Err(Refused::HeldByAnother);
                    }
                    *owner = Some(who);
                }
                // The holder releases its slot; the primary owner may clear either.
                Slot::Release => match owner {
                    Some(o) if *o != sender && self.primary != Some(sender) => return Err(Refused::HeldByAnother),
                    _ => *owner = None,
                },
            }
        }
        *self = next;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GCS: Sender = (255, 190);
    const AUTOPILOT: Sender = (1, 1);

    #[test]
    fn one_component_in_control_denies_another_until_it_releases() {
        let mut c = Control::default();
        assert!(c.allows(GCS) && c.allows(AUTOPILOT), "nobody in control: anyone");
        c.configure(GCS, [-2.0, -2.0, -1.0, -1.0]).unwrap();
        assert_eq!(c.primary, Some(GCS));
        assert!(c.allows(GCS) && !c.allows(AUTOPILOT));
        assert_eq!(
            c.configure(AUTOPILOT, [-2.0, -2.0, -1.0, -1.0]),
            Err(Refused::HeldByAnother)
        );
        assert_eq!(
            c.configure(AUTOPILOT, [-3.0, -3.0, -1.0, -1.0]),
            Err(Refused::HeldByAnother)
        );
        // The owner names a secondary.
        c.configure(GCS, [-1.0, -1.0, 1.0, 1.0]).unwrap();
        assert!(c.allows(AUTOPILOT));
        c.configure(GCS, [-3.0, -3.0, 0.0, 0.0]).unwrap();
        assert_eq!(c, Control::default());
    }

    #[test]
    fn parameters_that_mean_nothing_are_refused_and_change_nothing() {
        let mut c = Control::default();
        for bad in [
            [f32::NAN, 0.0, -1.0, -1.0],
            [1.5, 1.0, -1.0, -1.0],
            [300.0, 1.0, -1.0, -1.0],
            [-7.0, 0.0, -1.0, -1.0],
            [1.0, 1.0, -1.0, f32::INFINITY],
        ] {
            assert_eq!(c.configure(GCS, bad), Err(Refused::BadParameter), "{bad:?}");
            assert_eq!(c, Control::default());
        }
    }
}
