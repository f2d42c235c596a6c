//! Host-side code shared by gcud, gimbalctl and gimbalsim.
