"""SCons build script of the local AVR platform: compiles the project with avr-gcc from PATH,
links an .elf, converts it to .hex (flash) and prints flash/RAM use with avr-size."""

from SCons.Script import AlwaysBuild, Default, DefaultEnvironment

env = DefaultEnvironment()
board = env.BoardConfig()
mcu = board.get("build.mcu")
f_cpu = board.get("build.f_cpu")

env.Replace(
    AR="avr-gcc-ar",
    AS="avr-gcc",
    CC="avr-gcc",
    CXX="avr-g++",
    GDB="avr-gdb",
    OBJCOPY="avr-objcopy",
    RANLIB="avr-gcc-ranlib",
    SIZETOOL="avr-size",
    PROGSUFFIX=".elf",
    SIZEPROGREGEXP=r"^(?:\.text|\.data|\.bootloader)\s+(\d+).*",
    SIZEDATAREGEXP=r"^(?:\.data|\.bss|\.noinit)\s+(\d+).*",
    SIZECHECKCMD="$SIZETOOL -A -d $SOURCES",
)
env.Append(
    ASFLAGS=["-x", "assembler-with-cpp"],
    CCFLAGS=[
        "-Os",
        "-Wall",
        "-Wextra",
        "-ffunction-sections",
        "-fdata-sections",
        "-flto",
        "-mmcu=%s" % mcu,
    ],
    CFLAGS=["-std=gnu11"],
    CXXFLAGS=["-std=gnu++14", "-fno-exceptions", "-fno-rtti", "-fno-threadsafe-statics"],
    CPPDEFINES=[("F_CPU", "$BOARD_F_CPU")],
    LINKFLAGS=["-Os", "-mmcu=%s" % mcu, "-Wl,--gc-sections", "-flto", "-fuse-linker-plugin"],
    LIBS=["m"],
)
env.Append(
    BUILDERS=dict(
        ElfToHex=env.Builder(
            action=env.VerboseAction(
                " ".join(["$OBJCOPY", "-O", "ihex", "-R", ".eeprom", "$SOURCES", "$TARGET"]),
                "Building $TARGET",
            ),
            suffix=".hex",
        ),
    )
)

target_elf = env.BuildProgram()
target_hex = env.ElfToHex(target_elf)
size = env.Alias(
    "size",
    target_elf,
    env.VerboseAction("$SIZETOOL -C --mcu=%s $SOURCES" % mcu, "Calculating size $SOURCE"),
)
AlwaysBuild(size)
Default([target_hex, size])
