//! Cutting plans: the spiral gauge to cut before a measurement, and dilating a plan by the
//! measured kerf.
