//! Every reproduction's figures (SVG through [`aidnav_io::plot`]), one
//! function per figure file, drawn from the experiment's result:
//!
//! - consistency: [`nees_figure`];
//! - spec 10: Figs. 1–3 and the forced-switch sweep
//!   ([`extended_state_figures`]);
//! - spec 20, anomalies: the paper's Figs. 3–8 ([`anomaly_figures`]) and
//!   run 0's estimation errors ([`anomaly_example_figure`]);
//! - spec 20, outages: Fig. 9 ([`outage_predictors_figure`]), K_eff
//!   ([`efficiency_figure`]) and Fig. 10 ([`recovery_figure`]);
//! - spec 30: the one-axis group like the paper's Fig. 6 ([`group_figure`])
//!   and the formation ([`formation_figure`]), its accuracy against the
//!   network's latency and loss ([`network_sweep_figure`]).

mod anomalies;
mod consistency;
mod extended_state;
mod group;
mod outages;

pub use anomalies::{anomaly_example_figure, anomaly_figures};
pub use consistency::nees_figure;
pub use extended_state::extended_state_figures;
pub use group::{formation_figure, group_figure, network_sweep_figure};
pub use outages::{efficiency_figure, outage_predictors_figure, recovery_figure};
