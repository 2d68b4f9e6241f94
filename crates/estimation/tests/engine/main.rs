//! Engine tests against independent references (one test binary, submodules).

mod adaptive;
mod common;
mod consistency;
mod errors;
mod gmdh;
mod information;
mod kalman;
mod likelihood;
mod policies;
mod riccati;
mod smoother;
