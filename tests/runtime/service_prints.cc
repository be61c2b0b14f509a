// A program for tests/runtime/test_service_log.cc: prints a line to stdout (not flushed), writes
// READY_FILE, then waits (30 s at most) to be killed. "service": set up as every godhand service
// is (svc::Service, no DDS); "plain": a program that is not (the control: its line is lost).
// usage: godhand_test_service_prints service|plain READY_FILE
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "common/cli.h"
#include "runtime/service.h"

int main(int argc, char** argv) {
  if (argc != 3 || (std::string(argv[1]) != "service" && std::string(argv[1]) != "plain")) {
    std::fprintf(stderr, "usage: %s service|plain READY_FILE\n", argv[0]);
    return 2;
  }
  godhand::Cli cli("godhand_test_service_prints", "prints a line, then waits to be killed");
  godhand::svc::CommonOptions common;
  common.declare(cli);
  char* none[] = {argv[0], nullptr};
  cli.parse(1, none);
  std::unique_ptr<godhand::svc::Service> service;
  if (std::string(argv[1]) == "service") service = std::make_unique<godhand::svc::Service>("test", common, cli, /*steps=*/false);
  std::printf("a line printed before the kill\n");
  { std::ofstream(argv[2]) << "ready\n"; }
  for (int i = 0; i < 3000; ++i) ::usleep(10000);
  return 0;
}
