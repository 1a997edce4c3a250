fn main() {
    std::process::exit(spibench::cli::main());
}
