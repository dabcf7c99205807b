fn main() {
    println!("sahkd: command line not written yet");
}
