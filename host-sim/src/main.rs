use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = host_sim::cli::Cli::parse();
    // MPI, when launched by mpirun with the `mpi` feature (docs/MPI.md); finalised at the end.
    let _mpi = match host_sim::dist::start() {
        Ok(s) => s,
        Err(e) => return host_sim::dist::fail(&e),
    };
    match host_sim::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if host_sim::dist::is_finished(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => host_sim::dist::fail(&e),
    }
}
