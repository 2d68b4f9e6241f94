//! `aidnav simulate` and `aidnav zoo`: argument handling and printing; the
//! work is `aidnav_app::jobs::simulate` and `aidnav_app::jobs::zoo`.

use std::path::PathBuf;

use aidnav::app::jobs::simulate::{Simulation, SimulationFile, load_simulation, simulate_to_dir};
use aidnav::app::jobs::zoo::{zoo, zoo_table};
use anyhow::{Result, bail};
use clap::Args;

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Scenario file (TOML); see --print-scenario and zoo/*.toml.
    #[arg(value_name = "SCENARIO.toml")]
    scenario: Option<PathBuf>,
    /// Output directory (created if needed; the files of an earlier run in
    /// it are replaced).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Master seed (replaces the scenario's `seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Print the scenario with every value filled in (the defaults without
    /// SCENARIO) and exit.
    #[arg(long)]
    print_scenario: bool,
}

#[derive(Debug, Args)]
pub struct ZooArgs {
    /// Scenario files (TOML), e.g. zoo/*.toml.
    #[arg(value_name = "SCENARIO.toml", required = true)]
    scenarios: Vec<PathBuf>,
    /// Output directory: one folder per scenario (its log, truth and
    /// configuration), zoo.csv and summary.json.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// `aidnav simulate`.
pub fn run_simulate(a: SimulateArgs) -> Result<()> {
    let sim = match &a.scenario {
        Some(path) => load_simulation(path, a.seed)?,
        None => {
            let mut file = SimulationFile::default();
            if let Some(s) = a.seed {
                file.0.seed = s;
            }
            file.resolve()
                .map_err(|inv| anyhow::anyhow!("{}: {}", inv.key, inv.allowed))?
        }
    };
    if a.print_scenario {
        print!("{}", sim.to_toml());
        return Ok(());
    }
    let Some(out) = &a.out else {
        bail!("give --out DIR for the log (or --print-scenario to see the scenario)");
    };
    if a.scenario.is_none() {
        bail!("give a SCENARIO.toml to simulate (`--print-scenario` prints one to start from)");
    }
    report(&sim, out)
}

fn report(sim: &Simulation, out: &std::path::Path) -> Result<()> {
    let r = simulate_to_dir(sim, out)?;
    println!(
        "{}: seed {}, {:.0} s, {} IMU samples, {} GNSS fixes, {} wheel-speed, {} barometer samples",
        r.name,
        r.seed,
        r.duration_s,
        r.imu_samples,
        r.gnss_epochs,
        r.wheel_speed_samples,
        r.barometer_samples
    );
    for f in &r.files {
        println!("wrote {}", f.display());
    }
    println!("process it with: {}", r.process_command);
    Ok(())
}

/// `aidnav zoo`.
pub fn run_zoo(a: ZooArgs) -> Result<()> {
    let run = zoo(&a.scenarios, &a.out)?;
    print!("{}", zoo_table(&run.entries));
    for f in &run.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
