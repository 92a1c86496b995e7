// Writes the seed corpus for iowa_fuzz into DIR: small valid Iowa surfaces documents (from the
// tests' fixture) of a few sizes, eyes and undefined regions. Usage: make_iowa_seeds DIR

#include <filesystem>
#include <fstream>
#include <iostream>

#include "fixtures/iowa_xml.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::cerr << "usage: make_iowa_seeds DIR\n";
        return 64;
    }
    const std::filesystem::path dir(argv[1]);
    std::filesystem::create_directories(dir);
    int n = 0;
    for (const int x : {2, 6}) {
        for (const int z : {1, 3}) {
            for (const char* eye : {"OD", "OS", "?"}) {
                octshape::test::IowaDoc d;
                d.size_x = x;
                d.size_z = z;
                d.laterality = eye;
                d.undefined = {{x - 1, z - 1}};
                if (n % 2 == 1) d.labels = {10, 20, 140, 150}, d.base = {10, 20, 30, 34};
                std::ofstream(dir / ("seed" + std::to_string(n++) + ".xml")) << iowa_xml(d);
            }
        }
    }
    return 0;
}
